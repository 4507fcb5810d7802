"""Hand-built validation systems, shared by the simulator tests."""

from __future__ import annotations

import numpy as np

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


def copy_system(sysm, smoke_config):
    other = protocol.make_system(smoke_config, 3)
    other.restore(sysm.state())
    return other
