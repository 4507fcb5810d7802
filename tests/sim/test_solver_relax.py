"""Over-relaxed NLGS (solver.relax): same solutions as the plain sweep, validated range."""

import pytest

from tiltpile import config
from tiltpile.config import ConfigError
from tiltpile.sim.solver import natural_residual
from simhelpers import assert_column_forces, disk_column, make_system


@pytest.mark.parametrize("relax", [1.0, 1.5, 1.8])
def test_column_forces_with_over_relaxation(relax):
    """An 8-disk column: every normal force is the weight above, whatever omega."""
    sysm, r = disk_column()
    sysm.params["relax"] = relax
    rec = sysm.advance(5, 0.0, 0.0)
    assert rec.iterations.max() < 100_000
    assert_column_forces(sysm, r)
    assert natural_residual(sysm.ci, sysm.cj, sysm.c, sysm.vel) < 1e-12


def test_lone_contact_is_solved_in_one_sweep_at_any_relax():
    """The first sweep of a step is plain, so one disk on the floor needs no oscillation."""
    sysm = make_system([0.5], [[50.0, 0.5]], tol=1e-12)
    sysm.params["relax"] = 1.9
    rec = sysm.advance(3, 0.0, 0.0)
    assert rec.iterations.max() <= 2
    assert abs(sysm.velocity[0, 1]) < 1e-15


@pytest.mark.parametrize("value", ["0.0", "2.0", "-1.0"])
def test_relax_outside_0_2_is_refused(value):
    with pytest.raises(ConfigError, match="solver.relax"):
        config.load("smoke", None, [f"solver.relax={value}"])


def test_relax_default_is_plain_nlgs():
    assert config.load("smoke").solver.relax == 1.0
    assert config.load("paper").solver.relax == 1.0
