"""The interleaved sweep: its contact order, impulses carried across reordered lists, the contact
states derived from the impulses, and the same physics as the forward sweep."""

from __future__ import annotations

import numpy as np
import pytest

from simhelpers import assert_column_forces, copy_system, disk_column
from tiltpile.sim import detect, solver
from tiltpile.sim.solver import natural_residual


def _repeats(ci, cj, window):
    """Places k whose contact shares a body with one of the ``window`` contacts before it."""
    bad = []
    for k in range(len(ci)):
        before = set(ci[max(0, k - window):k]) | set(cj[max(0, k - window):k])
        if ci[k] in before or cj[k] in before:
            bad.append(k)
    return bad


def test_interleave_separates_a_chain():
    """A chain of 200 bodies, contacts (k, k + 1) in key order: every contact shares a body with
    the one before it. Interleaved, none does within the window, except where the lookahead
    runs dry at the end of the list."""
    ci = np.arange(200, dtype=np.int32)
    cj = ci + 1
    w = detect.INTERLEAVE_WINDOW
    assert len(_repeats(ci, cj, w)) == 199
    order = detect.interleave(ci, cj, 201)
    assert np.array_equal(np.sort(order), np.arange(200))
    bad = _repeats(ci[order], cj[order], w)
    assert bad and min(bad) >= 200 - 4 * w


def test_interleave_on_a_pile(settled_pile):
    """On the settled smoke pile (540 contacts): fewer than 2% of the places repeat a body within
    the window (key order: most of them), and the order stays close to key order."""
    s = settled_pile
    w = detect.INTERLEAVE_WINDOW
    by_key = np.argsort(s.key)            # the pile stores its list interleaved already
    ci, cj = s.ci[by_key], s.cj[by_key]
    order = detect.interleave(ci, cj, s.n + 3)
    assert np.array_equal(np.sort(order), np.arange(ci.size))
    assert len(_repeats(ci, cj, w)) > 0.5 * ci.size
    assert len(_repeats(ci[order], cj[order], w)) < 0.02 * ci.size
    assert np.abs(order - np.arange(ci.size)).max() < 8 * w
    assert len(_repeats(s.ci, s.cj, w)) < 0.02 * ci.size     # ... as the default sweep stores it


def test_wall_ids_both_ways():
    """Kernel indices N + 0, 1, 2 (floor, left, right) are run-file ids -1, -2, -3, and back;
    grains keep their index."""
    kernel = np.array([0, 3, 4, 5, 6, 7])                    # N = 5: grains 0, 3, 4; walls 5-7
    stored = detect.wall_ids(kernel, 5)
    np.testing.assert_array_equal(stored, [0, 3, 4, -1, -2, -3])
    np.testing.assert_array_equal(detect.kernel_ids(stored, 5), kernel)


def test_carry_impulses_in_any_order():
    """Impulses carry by pair whatever the order of the old and the new list."""
    rng = np.random.default_rng(4)
    old_key = rng.choice(10_000, size=300, replace=False)
    new_key = np.concatenate([rng.choice(old_key, 200, replace=False),
                              rng.choice(np.setdiff1d(np.arange(10_000), old_key), 50, replace=False)])
    rng.shuffle(new_key)
    old_p = rng.normal(size=(300, 2))
    new_p = np.full((250, 2), np.nan)
    assert detect.carry_impulses(old_key, old_p, new_key, new_p) == 200
    where = {k: p for k, p in zip(old_key, old_p)}
    for k, p in zip(new_key, new_p):
        np.testing.assert_array_equal(p, where.get(k, np.zeros(2)))


def test_status_follows_the_impulses():
    """Open where p_n = 0; sliding where |p_t| = mu p_n exactly, also with no slip velocity (a
    contact exactly at the Coulomb limit is fully mobilized); sticking inside the cone."""
    c = np.zeros((5, 8))
    c[:, 3] = 0.5
    c[:, 6] = [0.0, 0.2, 0.2, 0.2, 0.3]
    c[:, 7] = [0.0, 0.1, -0.1, 0.0999999, 0.5 * 0.3]
    status = np.full(5, 9, np.int8)
    solver.set_status(c, status)
    assert status.tolist() == [solver.OPEN, solver.SLIDE, solver.SLIDE, solver.STICK, solver.SLIDE]


def test_column_forces_with_the_interleaved_sweep():
    sysm, r = disk_column(sweep="interleaved")
    sysm.advance(5, 0.0, 0.0)
    assert_column_forces(sysm, r)


def test_interleaved_and_forward_sweeps_hold_the_same_pile(settled_pile, smoke_config):
    """From the settled smoke pile, 100 steps at rest with each sweep at tol 1e-6: the list is
    stored interleaved after the first rebuild (same pairs as key order), both converge on
    nearly every step at about the same number of sweeps (measured 17.8 and 17.6 per step, every
    step converged), end at a small natural residual, and the grains stay where they are."""
    ends, sweeps = {}, {}
    for sweep in ("forward", "interleaved"):
        s = copy_system(settled_pile, smoke_config)
        s.params.update(mode=solver.SWEEPS[sweep], tol=1e-6, max_iter=20_000)
        s.ref[:] = np.inf  # rebuild on the first step
        pos0 = s.pos.copy()
        rec = s.advance(100, 0.0, 0.0)
        assert rec.rebuilds >= 1
        assert (rec.iterations < 20_000).mean() > 0.9
        sweeps[sweep] = rec.iterations.mean()
        assert natural_residual(s.ci, s.cj, s.c, s.vel) < 1e-6
        assert np.abs(s.pos - pos0).max() < 1e-5
        ends[sweep] = s
    fw, il = ends["forward"], ends["interleaved"]
    assert np.all(np.diff(fw.key) > 0)
    assert not np.all(np.diff(il.key) > 0)
    assert np.array_equal(np.sort(il.key), fw.key)
    np.testing.assert_allclose(il.pos, fw.pos, atol=1e-6)
    assert sweeps["interleaved"] == pytest.approx(sweeps["forward"], rel=0.1)


@pytest.mark.parametrize("sweep", ["forward", "interleaved", "alternating", "random"])
def test_every_sweep_sets_status_from_impulses(settled_pile, smoke_config, sweep):
    s = copy_system(settled_pile, smoke_config)
    s.params.update(mode=solver.SWEEPS[sweep])
    s.advance(3, 0.0, 0.0)
    expect = np.empty_like(s.status)
    solver.set_status(s.c, expect)
    assert np.array_equal(s.status, expect)
    assert np.array_equal(s.status == solver.OPEN, s.c[:, 6] == 0)


def test_a_mode_change_reorders_the_stored_list(settled_pile, smoke_config):
    """Switching the sweep in ``params`` takes effect at the next ``advance``: the list is stored
    interleaved for the interleaved sweep and sorted by key for the others, pairs and impulses
    kept; a list already in order is left as it is (so a restored run continues unchanged)."""
    s = copy_system(settled_pile, smoke_config)
    s.params.update(mode=solver.FORWARD)
    s.advance(1, 0.0, 0.0)
    assert np.all(np.diff(s.key) > 0)
    pairs = dict(zip(s.key, map(tuple, s.c[:, 6:8])))
    s.params.update(mode=solver.INTERLEAVED)
    s._order_contacts()
    order = detect.interleave(*(np.sort(s.key) // (s.n + 3), np.sort(s.key) % (s.n + 3)), s.n + 3)
    np.testing.assert_array_equal(s.key, np.sort(s.key)[order])
    assert dict(zip(s.key, map(tuple, s.c[:, 6:8]))) == pairs
    before = s.key.copy()
    s._order_contacts()
    np.testing.assert_array_equal(s.key, before)
    s.params.update(mode=solver.RANDOM)
    s._order_contacts()
    assert np.all(np.diff(s.key) > 0)


@pytest.mark.parametrize("w", [1.0, 1.4])
def test_the_presets_sweep_is_the_named_contact_law_bit_for_bit(settled_pile, smoke_config, w):
    """``_sweep_stored`` (flat arrays, what the presets run) and ``_sweep_perm`` in the stored
    order (``_local_solution``, the contact law on named 2D columns) give the same impulses,
    velocities and sums, bit for bit, sweep after sweep, on a pile's contacts from rest."""
    s = copy_system(settled_pile, smoke_config)
    nc = s.ci.shape[0]
    assert nc > 50
    a_c, a_v = s.c.copy(), s.vel.copy()
    b_c, b_v = s.c.copy(), s.vel.copy()
    rng = np.random.default_rng(3)
    a_v[:-3, :3] += rng.normal(0.0, 0.01, (a_v.shape[0] - 3, 3))   # walls stay at rest
    b_v[:] = a_v
    perm = np.arange(nc, dtype=np.int64)
    for _ in range(5):
        sums_a = solver._sweep_stored(s.ci, s.cj, a_c.reshape(a_c.size), a_v.reshape(a_v.size), w)
        sums_b = solver._sweep_perm(s.ci, s.cj, b_c, b_v, perm, w)
        assert sums_a == sums_b
        assert np.array_equal(a_c, b_c) and np.array_equal(a_v, b_v)
    assert np.any(a_c[:, solver.IMPULSE] != s.c[:, solver.IMPULSE])  # the sweeps did something
