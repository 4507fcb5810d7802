"""Pruned sweeps (sim/solver.py): long steps leave out the open contacts that cannot close, and
change nothing by it, bit for bit, as long as none of them closes; when one would, the step does
not end on the pruned list."""

from __future__ import annotations

import numpy as np

from simhelpers import copy_system
from tiltpile.runner import system_from_frame
from tiltpile.sim import solver
from tiltpile.sim.rng import make_state
from tiltpile.store import open_run

STATE = ("pos", "rot", "vel", "ci", "cj", "c", "status")


def _left_out(s) -> int:
    """Contacts a pruned sweep would leave out of the current state."""
    v, c = s.vel, s.c
    un = ((v[s.ci, 0] - v[s.cj, 0]) * c[:, 0] + (v[s.ci, 1] - v[s.cj, 1]) * c[:, 1])
    return int(((c[:, 6] == 0.0) & (un + c[:, 2] > solver.PRUNE_MARGIN)).sum())


def _same_with_and_without(make, steps, theta0, dtheta):
    ends, its, upd = {}, {}, {}
    for prune in (False, True):
        s = make()
        s.params["prune"] = prune
        rec = s.advance(steps, theta0, dtheta)
        its[prune], upd[prune] = rec.iterations, rec.updates
        ends[prune] = s
    np.testing.assert_array_equal(its[True], its[False])
    for k in STATE:
        np.testing.assert_array_equal(getattr(ends[True], k), getattr(ends[False], k), err_msg=k)
    # local solves: every sweep over the whole list without pruning, fewer with it once past
    # PRUNE_AFTER sweeps (the contact list of a step can be rebuilt, so compare step by step)
    assert np.all(upd[True] <= upd[False])
    assert np.all(upd[True][its[True] > solver.PRUNE_AFTER + 1] < upd[False][its[True] > solver.PRUNE_AFTER + 1])
    return its[True], ends[True]


def test_pruned_sweeps_change_nothing_in_a_pile_held_to_a_tight_tol(settled_pile, smoke_config):
    """The settled smoke pile tilted 30 steps at tol 1e-9: every step runs past PRUNE_AFTER
    sweeps, a sixth of the candidate contacts are open and left out (85 of 534), and positions,
    velocities, impulses, states and sweep counts are those of the full sweeps, bit for bit."""
    def make():
        s = copy_system(settled_pile, smoke_config)
        s.params.update(tol=1e-9, max_iter=20_000)
        return s
    its, end = _same_with_and_without(make, 30, 0.0, 0.01)
    assert (its > solver.PRUNE_AFTER).all()
    assert _left_out(end) > 0.1 * end.ci.size


def test_pruned_sweeps_change_nothing_in_a_flow(smoke_run):
    """The smoke run of seed 1 at 11 deg (a rearrangement; steps at the cap of 1000, so they also
    end on a full sweep there): 20 steps from its frame 110 with and without pruning, bit for bit."""
    path, _ = smoke_run
    with open_run(path) as run:
        theta = float(run.theta_deg[110])
    cfg = system_from_frame(path, 110)[0]

    def make():
        return system_from_frame(path, 110)[1]
    its, end = _same_with_and_without(make, 20, theta, cfg.protocol.tilt_per_step_deg)
    assert (its > solver.PRUNE_AFTER).mean() > 0.5 and (its == cfg.solver.max_iter).any()
    assert _left_out(end) > 0


def test_a_left_out_contact_that_closes_is_caught():
    """Grain 0 falls at 5 d/s onto the floor (contact A, kept); grain 1, 1e-3 d above it, falls
    at 3 d/s (contact B: separating at 2 d/s, left out). Solving A stops grain 0, after which B
    closes at 3 d/s. The pruned sweeps converge on A alone, but do not report the step done."""
    vel = np.zeros((5, 4))
    vel[:2, 3] = 1.0                                  # unit masses; rows 2-4 are the walls
    vel[0, 1], vel[1, 1] = -5.0, -3.0
    ci, cj = np.array([0, 1], np.int32), np.array([2, 0], np.int32)
    c = np.zeros((2, 8))
    for a, (b, wnn) in enumerate([(0.0, 1.0), (1e-3 / 0.01, 2.0)]):
        c[a, :6] = (0.0, 1.0, b, 0.5, 1.0 / wnn, 1.0 / (3.0 * wnn))
    it, res, done, m = solver._pruned_sweeps(ci, cj, c, vel, 1e-12, 20, 30, 1.0)
    assert res == 0.0 and it == 22 and not done and m == 1
    assert c[0, 6] == 5.0 and c[1, 6] == 0.0          # B was not swept ...
    assert vel[1, 1] - vel[0, 1] + c[1, 2] < 0.0        # ... and would now overlap
    status = np.zeros(2, np.int8)
    it, res, updates = solver.nlgs(ci, cj, c, status, vel, 1e-12, 100, solver.INTERLEAVED,
                                   make_state(0), np.empty(2, np.int64), 1.0, True)
    assert res <= 1e-12 and c[1, 6] > 0.0 and vel[1, 1] - vel[0, 1] + c[1, 2] >= -1e-12
    assert updates == 2 * it                        # too short a solve to be pruned
