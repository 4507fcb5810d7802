"""z by counting rule (analysis/zcount.py) on hand-made configurations with known answers."""

import numpy as np
import pytest

from tiltpile.analysis import contacts as ct
from tiltpile.analysis import zcount as zc

ALL_IN = zc.Variant(walls=True, rattlers=True, bulk=False)
WALLS_OUT = zc.Variant(walls=False, rattlers=True, bulk=False)
NO_RATTLERS = zc.Variant(walls=True, rattlers=False, bulk=False)


def _z(pair, counted, fixed, bulk=None, variant=ALL_IN, min_contacts=2):
    fixed = np.asarray(fixed, bool)
    bulk = ~fixed if bulk is None else np.asarray(bulk, bool)
    z, n = zc.z_by_variant(np.asarray(pair).reshape(-1, 2), np.asarray(counted, bool), fixed, bulk,
                           (variant,), min_contacts)
    return z[0], n[0]


def _gap_z(pos, rad, fixed, box_length, g, variant=ALL_IN):
    pair, gap = zc.gap_contacts(pos, rad, fixed, box_length, 0.1)
    return _z(pair, gap <= g, fixed, variant=variant)


def test_square_of_four_touching_disks():
    # unit disks on the corners of a unit square, far from the walls: four contacts, no diagonals
    pos = np.array([[10.0, 10.0], [11.0, 10.0], [10.0, 11.0], [11.0, 11.0]])
    rad = np.full(4, 0.5)
    fixed = np.zeros(4, bool)
    pair, gap = zc.gap_contacts(pos, rad, fixed, 30.0, 0.1)
    assert pair.tolist() == [[0, 1], [0, 2], [1, 3], [2, 3]]
    assert gap == pytest.approx(0.0, abs=1e-12)
    for g in (0.0, 1e-4, 0.1):
        for v in zc.VARIANTS:  # every grain has 2 contacts: none is a rattler
            assert _z(pair, gap <= g, fixed, variant=v) == (pytest.approx(2.0), 4)
    # the diagonal (gap sqrt(2) - 1 = 0.41 d) is beyond the alert distance; with reach 0.5 it counts
    pair5, gap5 = zc.gap_contacts(pos, rad, fixed, 30.0, 0.5)
    assert len(pair5) == 6 and _z(pair5, gap5 <= 0.5, fixed)[0] == pytest.approx(3.0)


def test_a_gap_of_five_hundredths_counts_from_g_005():
    # grain 1 is 0.05 d from grain 0 (3.05 - 2.0 = 1.05 - 2e-16 in floating point)
    pos = np.array([[2.0, 5.0], [3.05, 5.0]])
    rad = np.full(2, 0.5)
    fixed = np.zeros(2, bool)
    pair, gap = zc.gap_contacts(pos, rad, fixed, 20.0, 0.1)
    assert pair.tolist() == [[0, 1]] and gap[0] == pytest.approx(0.05)
    for g, z in ((0.0, 0.0), (0.01, 0.0), (0.049, 0.0), (0.05, 1.0), (0.1, 1.0)):
        assert _gap_z(pos, rad, fixed, 20.0, g)[0] == pytest.approx(z), g
    # beyond the reach it is not even a candidate
    assert len(zc.gap_contacts(pos, rad, fixed, 20.0, 0.04)[0]) == 0


def test_wall_and_fixed_grain_contacts_count_only_with_walls_in():
    # grain 0 touches the left wall and grain 1; grain 1 touches grain 0 and the fixed grain 2 below
    pos = np.array([[0.5, 5.0], [1.5, 5.0], [1.5, 4.0]])
    rad = np.full(3, 0.5)
    fixed = np.array([False, False, True])
    pair, gap = zc.gap_contacts(pos, rad, fixed, 20.0, 0.1)
    assert sorted(map(tuple, pair.tolist())) == [(0, -2), (0, 1), (1, 2)]
    assert _gap_z(pos, rad, fixed, 20.0, 1e-9, ALL_IN) == (pytest.approx(2.0), 2)   # (2 + 2) / 2
    assert _gap_z(pos, rad, fixed, 20.0, 1e-9, WALLS_OUT) == (pytest.approx(1.0), 2)  # (1 + 1) / 2
    # fixed grains are never counted and have no wall contacts (fixed grain 2 sits on the floor)
    pos2 = np.array([[5.0, 1.5], [5.0, 0.5]])
    pair2, _ = zc.gap_contacts(pos2, np.full(2, 0.5), np.array([False, True]), 20.0, 0.1)
    assert pair2.tolist() == [[0, 1]]
    assert zc.boundary_contacts(pair, fixed).tolist() == [True, False, True]


def test_a_rattler_is_removed_with_its_contacts():
    # a triangle 0-1-2 and grain 3 hanging on grain 2 by one contact: grain 3 is a rattler
    pair = np.array([[0, 1], [0, 2], [1, 2], [2, 3]])
    fixed = np.zeros(4, bool)
    on = np.ones(4, bool)
    assert _z(pair, on, fixed, variant=ALL_IN) == (pytest.approx(8 / 4), 4)
    assert _z(pair, on, fixed, variant=NO_RATTLERS) == (pytest.approx(6 / 3), 3)
    # rattlers are found on the counted network, walls included: a wall contact saves grain 3
    pair_w = np.vstack([pair, [[3, -1]]])
    assert _z(pair_w, np.ones(5, bool), fixed, variant=NO_RATTLERS) == (pytest.approx(9 / 4), 4)
    # ... and stays saved when wall contacts are then left out of z
    v = zc.Variant(walls=False, rattlers=False, bulk=False)
    assert _z(pair_w, np.ones(5, bool), fixed, variant=v) == (pytest.approx(8 / 4), 4)


def test_bulk_restriction_counts_contacts_to_outside_grains_once_per_grain():
    # chain 0-1-2-3, bulk = {1, 2}: z_1 = z_2 = 2, N = 2 -> z = 2 (contacts 0-1 and 2-3 count one half)
    pair = np.array([[0, 1], [1, 2], [2, 3]])
    fixed = np.zeros(4, bool)
    bulk = np.array([False, True, True, False])
    v = zc.Variant(walls=True, rattlers=True, bulk=True)
    assert _z(pair, np.ones(3, bool), fixed, bulk, v) == (pytest.approx(2.0), 2)
    # with rattlers out, the chain's ends (1 contact) go, and with them contacts 0-1 and 2-3
    v = zc.Variant(walls=True, rattlers=False, bulk=True)
    assert _z(pair, np.ones(3, bool), fixed, bulk, v) == (pytest.approx(1.0), 2)
    # no grain selected: NaN
    assert np.isnan(_z(pair, np.ones(3, bool), fixed, np.zeros(4, bool), v)[0])


def test_force_thresholds_are_relative_to_the_mean_active_force():
    fn = np.array([0.0, 1e-4, 1.0, 2.0, 0.9999])   # mean over f_n > 0: 3.9999 / 4 ~ 1
    assert zc.force_mask(fn, 0.0).tolist() == [False, True, True, True, True]
    assert zc.force_mask(fn, 1e-5).tolist() == [False, True, True, True, True]
    assert zc.force_mask(fn, 1e-3).tolist() == [False, False, True, True, True]
    assert zc.force_mask(fn, 1.0).tolist() == [False, False, False, True, False]
    assert not zc.force_mask(np.zeros(3), 1e-3).any()
    with pytest.raises(ValueError, match="threshold"):
        zc.force_mask(fn, -1.0)


def test_frame_z_on_the_triangular_pile_matches_the_analysis(pile_factory, contacts_factory):
    # the pile of test_analysis_observables: bulk z 36/7, all mobile grains 66/14
    pos, rad, fixed, row = pile_factory(4, 4)
    pair = contacts_factory(pos, rad, 4.0)
    force = np.column_stack([np.ones(len(pair)), np.zeros(len(pair))])
    weak = np.flatnonzero((pair[:, 0] == 16) & (pair[:, 1] == 17))[0]
    force[weak, 0] = 1e-3   # one weak contact in the top row: f_n > 0 counts it, f_n > 1e-2 <f_n> not
    keep = zc.mobile_contacts(pair, fixed)
    bulk = ct.bulk_mask(pos, rad, fixed, pair[keep], 4.0)
    assert bulk.sum() == 7
    ft, gt = (0.0, 1e-2), (1e-9, 0.1)
    z, n = zc.frame_z(pos, rad, fixed, 4.0, pair, force, bulk, ft, gt)
    assert z.shape == n.shape == (4, len(zc.VARIANTS))
    ia = zc.VARIANTS.index(zc.ANALYSIS_VARIANT)
    bc = ct.bulk_coordination(pair[keep], force[keep, 0] > 0, np.zeros(keep.sum(), bool), bulk, fixed)
    assert z[0, ia] == pytest.approx(bc["z"]) == pytest.approx(36 / 7)
    assert n[0, ia] == 7
    assert z[2, ia] == pytest.approx(36 / 7)                        # geometric contacts, g = 1e-9
    iall = zc.VARIANTS.index(zc.Variant(True, False, False))
    assert z[0, iall] == pytest.approx(66 / 14)
    assert z[1, iall] == pytest.approx(64 / 14)                     # the weak contact dropped
    # without wall and fixed-grain contacts the bulk loses the two wall contacts of row 2 (7, 10)
    iw = zc.VARIANTS.index(zc.Variant(False, False, True))
    assert z[0, iw] == pytest.approx(34 / 7)
    # at g = 0.1 d nothing new is found in a lattice of touching unit disks (next gap 0.73 d)
    assert z[3] == pytest.approx(z[2])


def test_gap_contacts_agree_with_brute_force(contacts_factory):
    rng = np.random.default_rng(4)
    n, L = 120, 12.0
    rad = rng.uniform(0.4, 0.6, n)
    pos = np.column_stack([rng.uniform(0.3, L - 0.3, n), rng.uniform(0.3, 8.0, n)])
    fixed = np.zeros(n, bool)
    fixed[:10] = True
    reach = 0.1
    pair, gap = zc.gap_contacts(pos, rad, fixed, L, reach)
    brute = contacts_factory(pos, rad, L, tol=reach)
    bi, bj = brute[:, 0], brute[:, 1]
    brute = brute[~(fixed[bi] & (bj < 0)) & ~((bj >= 0) & fixed[bi] & fixed[np.maximum(bj, 0)])]
    assert sorted(map(tuple, pair.tolist())) == sorted(map(tuple, brute.tolist()))
    assert gap == pytest.approx(ct.contact_gaps(pair, pos, rad, L))
    assert (gap <= reach).all()


def test_grids_and_rule_names():
    assert zc.gap_grid(0.1) == zc.GAP_THRESHOLDS
    assert zc.gap_grid(0.03)[-3:] == (0.01, 0.02, 0.03)
    with pytest.raises(ValueError):
        zc.gap_grid(0.0)
    r = zc.rules((0.0, 1e-3), (0.0, 0.01))
    assert [x.key for x in r] == ["f_n>0", "f_n>0.001<f_n>", "gap<=0", "gap<=0.01"]
    assert zc.rule_key(r[0], zc.ANALYSIS_VARIANT) == "f_n>0 walls=in rattlers=out grains=bulk"
    assert len(set(zc.VARIANTS)) == 8 and zc.VARIANTS[0] == zc.ANALYSIS_VARIANT


def test_first_reaching():
    g = [0.0, 1e-3, 1e-2, 1e-1]
    assert zc.first_reaching(g, [3.0, 3.2, 3.6, 4.0]) == {
        "threshold": 1e-2, "interpolated": pytest.approx(10 ** -2.25)}
    assert zc.first_reaching(g, [3.0, 3.2, 3.4, 3.45]) == {"threshold": None, "interpolated": None}
    assert zc.first_reaching(g, [3.6, 3.7, 3.8, 3.9])["threshold"] == 0.0
    assert zc.first_reaching(g, [3.0, 4.0, 4.1, 4.2])["interpolated"] == pytest.approx(5e-4)
    assert zc.first_reaching(g, [3.0, np.nan, 3.6, 4.0])["threshold"] == 1e-2
