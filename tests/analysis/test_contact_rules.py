"""The contact rule, the lost-contact rule and the frame stride as analysis parameters
(tables.DEFAULT_PARAMS: contact_rule, lost_rule, frame_stride), against brute-force counts."""

from __future__ import annotations

import numpy as np
import pytest

from tiltpile.analysis import contacts as ct
from tiltpile.analysis import tables


def _spread_pile(pile_factory, gap):
    """A triangular pile of unit disks whose neighbours stand ``gap`` (d) apart (the lattice
    scaled about the bottom row), the side walls ``gap`` from the outer grains."""
    pos, radius, fixed, row = pile_factory(8, 6)
    pos = pos.copy()
    s = 1.0 + gap
    pos[:, 0] = 0.5 + gap + (pos[:, 0] - 0.5) * s
    pos[:, 1] = 0.5 + (pos[:, 1] - 0.5) * s
    return pos, radius, fixed, row, 1.0 + 7.0 * s + 2.0 * gap


def _frame(radius, fixed, L, pos, pair, force, status, **params):
    zero = np.zeros_like(pos)
    row, clusters, keep = tables.frame_observables(radius, fixed, L, pos, zero, np.zeros(len(radius)),
                                                   pair, force, status, 0.0, **params)
    return row, clusters, keep


def _oracle_z(pos, radius, fixed, L, tol, contacts_factory, **params):
    """Bulk z with every pair within ``tol`` (brute force) counted as a force-bearing contact."""
    pair = contacts_factory(pos, radius, L, tol=tol)
    moving = ~fixed[pair[:, 0]] | ((pair[:, 1] >= 0) & ~fixed[np.maximum(pair[:, 1], 0)])
    pair = pair[moving]
    force = np.column_stack([np.ones(len(pair)), np.zeros(len(pair))])
    row, _, _ = _frame(radius, fixed, L, pos, pair, force, np.ones(len(pair), np.int8), **params)
    return row["z"], row["n_active"]


def test_a_gap_rule_counts_every_pair_within_the_gap(pile_factory, contacts_factory):
    """Neighbours 0.01 d apart, only the contacts with the bottom row listed (with force): the
    force rule counts those; gap:0.005 adds nothing; gap:0.02 counts every neighbour pair and
    wall, as a brute-force search of the pairs within 0.02 d does (a triangular bulk: z near 6),
    on the same bulk grains (the layers come from the listed contacts)."""
    pos, radius, fixed, _, L = _spread_pile(pile_factory, 0.01)
    every = contacts_factory(pos, radius, L, tol=0.02)
    j = every[:, 1]
    to_bottom = fixed[every[:, 0]] & (j >= 0) & ~fixed[np.maximum(j, 0)]
    listed = every[to_bottom]
    k = len(listed)
    force = np.column_stack([np.ones(k), np.zeros(k)])
    status = np.ones(k, np.int8)
    by_force, _, _ = _frame(radius, fixed, L, pos, listed, force, status)
    near, _, _ = _frame(radius, fixed, L, pos, listed, force, status, contact_rule="gap:0.005")
    far, _, _ = _frame(radius, fixed, L, pos, listed, force, status, contact_rule="gap:0.02")
    assert by_force["n_active"] == near["n_active"] == k > 5
    z_oracle, n_oracle = _oracle_z(pos, radius, fixed, L, 0.02, contacts_factory)
    assert far["n_active"] == n_oracle > 100
    assert far["z"] == z_oracle
    assert 5.5 < far["z"] <= 6.0
    assert far["n_bulk"] + far["n_rattlers"] == by_force["n_bulk"] + by_force["n_rattlers"]


def test_touching_counts_every_listed_contact_and_force_only_the_loaded(pile_factory,
                                                                         contacts_factory):
    """Every contact of a touching pile listed, half of them with no force (status 0): the
    touching rule counts them all, as gap:0 does from the positions; the force rule half."""
    pos, radius, fixed, _ = pile_factory(8, 6)
    L = 8.0
    pair = contacts_factory(pos, radius, L)
    keep = ~fixed[pair[:, 0]] | ((pair[:, 1] >= 0) & ~fixed[np.maximum(pair[:, 1], 0)])
    pair = pair[keep]
    loaded = np.arange(len(pair)) % 2 == 0
    force = np.column_stack([loaded.astype(float), np.zeros(len(pair))])
    status = loaded.astype(np.int8)
    f, _, _ = _frame(radius, fixed, L, pos, pair, force, status)
    t, _, _ = _frame(radius, fixed, L, pos, pair, force, status, contact_rule="touching")
    g, _, _ = _frame(radius, fixed, L, pos, pair, force, status, contact_rule="gap:1e-9")
    assert f["n_active"] == loaded.sum()
    assert t["n_active"] == g["n_active"] == len(pair)
    assert t["z"] == g["z"] > f["z"]


def test_a_pair_is_lost_when_it_leaves_the_rules_list(pile_factory, contacts_factory):
    """From frame k to k + 1 every force vanishes and one grain moves up: the force rule loses
    every contact; gap:0.01 loses only the contacts of the moved grain that opened beyond 0.01
    (it moved 0.05 d), not those it kept within reach; the mixed rule (the list for z, losses by
    force) loses every contact again."""
    pos, radius, fixed, row = pile_factory(8, 6)
    L = 8.0
    pair = contacts_factory(pos, radius, L)
    pair = pair[~fixed[pair[:, 0]] | ((pair[:, 1] >= 0) & ~fixed[np.maximum(pair[:, 1], 0)])]
    force = np.column_stack([np.ones(len(pair)), np.zeros(len(pair))])
    status = np.ones(len(pair), np.int8)
    top = np.flatnonzero(row == row.max())[3]
    pos2 = pos.copy()
    pos2[top, 1] += 0.05
    empty = (np.empty((0, 2), np.int32), np.empty((0, 2)), np.empty(0, np.int8))

    def lost(**params):
        _, _, a = _frame(radius, fixed, L, pos, pair, force, status, **params)
        _, _, b = _frame(radius, fixed, L, pos2, *empty, **params)
        return tables.failure_between(a, b, fixed)["n_lost"]

    moved = (pair[:, 0] == top) | (pair[:, 1] == top)
    gaps = ct.contact_gaps(pair, pos2, radius, L)
    assert lost() == len(pair)
    assert lost(contact_rule="gap:0.01") == int((moved & (gaps > 0.01)).sum()) > 0
    assert lost(contact_rule="gap:0.01", lost_rule="force") == len(pair)


def test_every_kth_frame_is_the_run_of_those_frames(tmp_path, pile_factory, contacts_factory,
                                                    run_writer):
    """frame_stride 2 on five frames gives the tables of a run file holding frames 0, 2 and 4,
    but for the stored frame index (and the step and time read from the file)."""
    pos, radius, fixed, row = pile_factory(8, 6)
    L = 8.0
    pair = contacts_factory(pos, radius, L)
    rng = np.random.default_rng(3)
    frames, cts = [], []
    for k in range(5):
        loaded = rng.random(len(pair)) < 0.8
        frames.append(pos)
        cts.append((pair, np.column_stack([loaded * 1.0, np.zeros(len(pair))]),
                    np.where(loaded, 1, 0).astype(np.int8)))
    theta = [0.0, 0.1, 0.2, 0.3, 0.4]
    run_writer(tmp_path / "run_0001.h5", radius, fixed, L, frames, cts, theta, seed=1)
    run_writer(tmp_path / "run_0002.h5", radius, fixed, L, frames[::2], cts[::2], theta[::2], seed=1)
    a_fr, a_cl = tables.run_observables(tmp_path / "run_0001.h5", frame_stride=2)
    b_fr, b_cl = tables.run_observables(tmp_path / "run_0002.h5")
    assert a_fr["frame"].tolist() == [0, 2, 4] and b_fr["frame"].tolist() == [0, 1, 2]
    assert a_cl["frame"].isin([0, 2, 4]).all()
    skip = ["frame", "step", "time"]
    assert a_fr.drop(columns=skip).equals(b_fr.drop(columns=skip))
    assert a_cl.drop(columns=["frame"]).equals(b_cl.drop(columns=["frame"]))
    assert (a_fr["n_lost"].iloc[:2] > 0).all()


@pytest.mark.parametrize("params, match", [
    ({"contact_rule": "gap:-0.1"}, "contact rule"),
    ({"contact_rule": "gap:x"}, "contact rule"),
    ({"contact_rule": "overlap"}, "contact rule"),
    ({"lost_rule": "gap:"}, "contact rule"),
    ({"frame_stride": 0}, "frame_stride"),
    ({"frame_stride": 1.5}, "frame_stride"),
    ({"frame_stride": True}, "frame_stride"),
])
def test_bad_rules_and_strides_are_refused_in_one_line(params, match):
    with pytest.raises(ValueError, match=match) as e:
        tables._params(params)
    assert "\n" not in str(e.value)
