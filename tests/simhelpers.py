"""Hand-built validation systems, shared by the simulator tests."""

from __future__ import annotations

import numpy as np
import pytest

from tiltpile.sim import protocol
from tiltpile.sim.rng import make_state
from tiltpile.sim.solver import SWEEPS
from tiltpile.sim.step import System


def make_system(radius, pos, *, fixed=None, box_length=100.0, dt=0.01, mu=0.5, mu_wall=0.5,
                tol=1e-12, max_iter=10_000, sweep="forward", alert=0.1, gravity=1.0, slop=0.0):
    """A System from explicit grains (mass = disk area), for hand-built validation cases."""
    radius = np.asarray(radius, float)
    fixed = np.zeros(radius.size, bool) if fixed is None else np.asarray(fixed, bool)
    inv_mass = np.where(fixed, 0.0, 1.0 / (np.pi * radius**2))
    return System(radius, fixed, np.asarray(pos, float), inv_mass, make_state(0), box_length=box_length,
                  dt=dt, alert=alert, mu=mu, mu_wall=mu_wall, tol=tol, max_iter=max_iter,
                  mode=SWEEPS[sweep], slop=slop, gravity=gravity)


def disk_column(n: int = 8, seed: int = 1, **kw):
    """``n`` touching disks (radii uniform in [0.4, 0.6]) stacked on the floor at x = 50, solved
    to tol 1e-14; ``kw`` go to :func:`make_system`. Returns (system, radii)."""
    r = np.random.default_rng(seed).uniform(0.4, 0.6, size=n)
    y = np.cumsum(2 * r) - r
    sysm = make_system(r, np.column_stack([np.full(n, 50.0), y]), tol=1e-14, max_iter=100_000, **kw)
    return sysm, r


def assert_column_forces(sysm, r) -> None:
    """Every contact of a settled :func:`disk_column` carries the weight above it (rel 1e-8) and no
    tangential force: the floor and n - 1 grain-grain contacts, nothing else."""
    pair, force, _ = sysm.contacts(active_only=True)
    m = np.pi * np.asarray(r) ** 2
    assert len(pair) == len(m)
    for (i, j), (fn, ft) in zip(pair, force):
        expected = m[i:].sum() if j < 0 else m[max(i, j):].sum()
        assert fn == pytest.approx(expected, rel=1e-8)
        assert abs(ft) < 1e-10 * expected


def copy_system(sysm, smoke_config):
    other = protocol.make_system(smoke_config, 3)
    other.restore(sysm.state())
    return other


def assert_same_run(a, b) -> None:
    """Two run files hold the same run, array for array (bit-identical)."""
    import h5py

    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        # trajectories first (positions, contacts), derived per-frame columns after: a mismatch
        # then says whether the run itself differs or only a diagnostic computed from it
        for group in ("particles", "contacts", "frames"):
            assert sorted(fa[group]) == sorted(fb[group])
            for name in sorted(fa[group], key=lambda n: (n not in ("position", "velocity"), n)):
                np.testing.assert_array_equal(fa[group][name][()], fb[group][name][()],
                                              err_msg=f"{a}: {group}/{name}")
        assert fa.attrs["seed"] == fb.attrs["seed"] and fa.attrs["config_hash"] == fb.attrs["config_hash"]
