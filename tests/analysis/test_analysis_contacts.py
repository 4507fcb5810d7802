"""Contact observables on hand-built networks with known answers."""

import numpy as np
import pytest

from tiltpile.analysis import contacts as ct


def _lattice_forces(pair):
    return np.column_stack([np.ones(len(pair)), np.zeros(len(pair))]), np.ones(len(pair), np.int8)


def test_triangular_lattice_interior_z_is_six(pile_factory, contacts_factory):
    pos, rad, fixed, row = pile_factory(10, 8)
    pair = contacts_factory(pos, rad, 10.0)
    force, status = _lattice_forces(pair)
    z_i = ct.contact_counts(len(rad), pair, ct.active_mask(force))
    # interior grains: not in the bottom/top row and away from the side walls
    interior = (row >= 2) & (row <= 7) & (pos[:, 0] > 1.6) & (pos[:, 0] < 8.4)
    assert interior.sum() > 20
    assert np.all(z_i[interior] == 6)
    z, n_m, n = ct.coordination(z_i, np.zeros_like(z_i), interior)
    assert (z, n_m, n) == (6.0, 0.0, interior.sum())
    assert ct.dz_gen(z, n_m) == pytest.approx(3.0)


def test_square_lattice_z_four_and_mobilization():
    m = 6
    idx = np.arange(m * m).reshape(m, m)
    horiz = np.column_stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()])
    vert = np.column_stack([idx[:-1, :].ravel(), idx[1:, :].ravel()])
    pair = np.vstack([horiz, vert])
    force = np.column_stack([np.ones(len(pair)), np.zeros(len(pair))])
    status = np.r_[np.full(len(horiz), 2), np.ones(len(vert))].astype(np.int8)   # horizontals slide
    act = ct.active_mask(force)
    mob = ct.mobilized_mask(force, status)
    z_i = ct.contact_counts(m * m, pair, act)
    m_i = ct.contact_counts(m * m, pair, mob)
    interior = np.zeros((m, m), bool)
    interior[1:-1, 1:-1] = True
    interior = interior.ravel()
    z, n_m, n = ct.coordination(z_i, m_i, interior)
    assert (z, n_m, n) == (4.0, 1.0, 16)          # 2 sliding contacts per grain -> n_m = 2/2
    assert ct.dz_gen(z, n_m) == 0.0                # exactly marginal: 4 = 3 + 1
    # whole lattice: z = 2 N_c / N with N_c = 2 m (m - 1) bonds
    zall, nmall, _ = ct.coordination(z_i, m_i, np.ones(m * m, bool))
    assert zall == pytest.approx(2 * 2 * m * (m - 1) / m**2)
    assert nmall == pytest.approx(m * (m - 1) / m**2)


def test_mobilized_threshold_alternative():
    force = np.array([[1.0, 0.5], [1.0, 0.49], [1.0, -0.5], [0.0, 0.0], [2.0, 0.9]])
    status = np.array([2, 1, 1, 2, 1], np.int8)
    assert ct.mobilized_mask(force, status).tolist() == [True, False, False, False, False]
    assert ct.mobilized_mask(force, mu=0.5, eps=0.0).tolist() == [True, False, True, False, False]
    assert ct.mobilized_mask(force, mu=0.5, eps=0.05).tolist() == [True, True, True, False, False]
    with pytest.raises(ValueError):
        ct.mobilized_mask(force)


def test_pile_layers_and_bulk_z(pile_factory, contacts_factory):
    # width 6: even rows 6 grains touching both side walls, odd rows 5 grains; 4 mobile rows
    pos, rad, fixed, row = pile_factory(6, 4)
    pair = contacts_factory(pos, rad, 6.0)
    gaps = ct.contact_gaps(pair, pos, rad, 6.0)
    assert np.allclose(gaps, 0.0, atol=1e-12)
    assert np.array_equal(ct.bottom_layer(pair, gaps, fixed), row == 1)
    assert np.array_equal(ct.top_layer(pos, rad, fixed, 6.0), row == 4)
    bulk = ct.bulk_mask(pos, rad, fixed, pair, 6.0)
    assert np.array_equal(bulk, (row == 2) | (row == 3))
    force, status = _lattice_forces(pair)
    res = ct.bulk_coordination(pair, ct.active_mask(force), np.zeros(len(pair), bool), bulk, fixed)
    # row 2: 4 interior grains z = 6, 2 end grains z = 4 (wall, neighbour, one below, one above)
    # row 3: 3 interior grains z = 6, 2 end grains z = 5 (no wall)  -> (24 + 8 + 18 + 10) / 11
    assert res["z"] == pytest.approx(60 / 11)
    assert res["n"] == 11 and res["n_rattlers"] == 0 and res["n_m"] == 0.0
    assert res["dz_gen"] == pytest.approx(60 / 11 - 3)


def test_bottom_layer_ignores_candidates_beyond_touch_tol():
    pos = np.array([[0.5, 0.5], [0.5, 1.6], [2.0, 0.54]])
    rad = np.array([0.5, 0.5, 0.5])
    fixed = np.array([True, False, False])
    pair = np.array([[0, 1], [2, -1]])       # grain 1 is 0.1 d above grain 0: a candidate, not touching
    gaps = ct.contact_gaps(pair, pos, rad, 10.0)
    assert gaps == pytest.approx([0.1, 0.04])
    assert ct.bottom_layer(pair, gaps, fixed, touch_tol=0.05).tolist() == [False, False, True]
    assert ct.bottom_layer(pair, gaps, fixed, touch_tol=0.2).tolist() == [False, True, True]


def test_top_layer_finds_small_grain_in_a_dip():
    # two big grains and a small one resting high in the gap between them: exposed from above
    pos = np.array([[1.0, 0.6], [2.2, 0.6], [1.6, 1.0], [1.6, 0.2]])
    rad = np.array([0.6, 0.6, 0.2, 0.2])
    top = ct.top_layer(pos, rad, np.zeros(4, bool), 3.2)
    assert top.tolist() == [True, True, True, False]


def test_rattler_rule_removes_grain_and_its_contacts():
    # 4 grains in a square ring (each z = 2) plus grain 4 touching only grain 0
    pair = np.array([[0, 1], [1, 2], [2, 3], [0, 3], [0, 4]])
    force = np.column_stack([np.ones(5), np.zeros(5)])
    act = ct.active_mask(force)
    fixed = np.zeros(5, bool)
    res = ct.bulk_coordination(pair, act, np.zeros(5, bool), np.ones(5, bool), fixed)
    assert res["rattler"].tolist() == [False, False, False, False, True]
    assert res["n"] == 4 and res["n_rattlers"] == 1
    assert res["z"] == 2.0                    # grain 0's contact with the rattler is dropped
    off = ct.bulk_coordination(pair, act, np.zeros(5, bool), np.ones(5, bool), fixed, min_contacts=0)
    assert off["z"] == pytest.approx(10 / 5)


def test_wall_and_outside_contacts_count_half_in_nc():
    # grain 0 (selected) touches the floor, grain 1 (not selected) and grain 2 (selected)
    pair = np.array([[0, -1], [0, 1], [0, 2], [2, -2]])
    act = np.ones(4, bool)
    mob = np.array([True, False, True, False])
    z_i = ct.contact_counts(3, pair, act)
    m_i = ct.contact_counts(3, pair, mob)
    assert z_i.tolist() == [3, 1, 2] and m_i.tolist() == [2, 0, 1]
    z, n_m, n = ct.coordination(z_i, m_i, np.array([True, False, True]))
    # N_c = 1 (0-2) + 1/2 (floor) + 1/2 (0-1) + 1/2 (wall) = 2.5 -> z = 2 * 2.5 / 2
    # N_m = 1 (0-2) + 1/2 (floor)                         -> n_m = 1.5 / 2
    assert z == 2.5 and n_m == 0.75 and n == 2


def test_lost_contacts_matched_by_pair_when_order_changes():
    rng = np.random.default_rng(3)
    n = 50
    pair_a = np.array([[i, j] for i in range(20) for j in (i + 1, i + 5)] + [[3, -1], [7, -3]])
    active_a = np.ones(len(pair_a), bool)
    active_a[4] = False                              # open at a: can't be lost
    drop = {2, 11, 40}                               # absent from b's list
    zero_b = {17}                                    # listed at b with f_n = 0
    keep = [c for c in range(len(pair_a)) if c not in drop]
    perm = rng.permutation(keep)
    pair_b = np.vstack([pair_a[perm], [[30, 31], [9, -2]]])     # plus new contacts
    active_b = np.ones(len(pair_b), bool)
    active_b[np.flatnonzero(perm == 17)] = False
    lost = ct.lost_contacts(pair_a, active_a, pair_b, active_b, n)
    assert set(np.flatnonzero(lost)) == drop | zero_b
    # the same contacts, unpermuted, lose nothing
    assert not ct.lost_contacts(pair_a, active_a, pair_a, np.ones(len(pair_a), bool), n).any()
    failing = ct.failing_grains(n, pair_a, lost)
    expect = set(pair_a[sorted(drop | zero_b)].ravel()) - {-1, -2, -3}
    assert set(np.flatnonzero(failing)) == expect


def test_kinetic_energy_of_a_disk():
    e_t, e_r = ct.kinetic_energy(np.array([0.5]), np.array([[3.0, 4.0]]), np.array([2.0]))
    m = np.pi * 0.25
    assert e_t[0] == pytest.approx(0.5 * m * 25.0)
    assert e_r[0] == pytest.approx(0.5 * (0.5 * m * 0.25) * 4.0)


def test_gravity_vector_points_downslope():
    assert ct.gravity_vector(0.0) == pytest.approx([0.0, -1.0])
    assert ct.gravity_vector(30.0) == pytest.approx([0.5, -np.sqrt(3) / 2])
