"""Critical clusters with known membership, size, z, n_m and orientation."""

import numpy as np
import pytest

from tiltpile.analysis import clusters as cl
from tiltpile.analysis import contacts as ct

# 10 grains, grain 9 fixed.
#   0 -m- 1 --- 2 -m- wall      cluster A: {0, 1, 2} linked by contacts; {0, 1} + {2} by mobilized
#             2 --- 3           3 has no mobilized contact: not critical
#   5 -m- 6,  6 --- 7 (open)    cluster B: {5, 6}; 7 touches 6 only with f_n = 0
#   8 -m- 9 (fixed)             cluster C: {8}; the fixed grain 9 is never critical
PAIR = np.array([[0, 1], [1, 2], [2, -2], [2, 3], [5, 6], [6, 7], [8, 9], [4, -1]])
FN = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 1.0, 1.0])
STATUS = np.array([2, 1, 2, 1, 2, 0, 2, 1], np.int8)
FIXED = np.zeros(10, bool)
FIXED[9] = True


def _masks():
    force = np.column_stack([FN, 0.5 * FN])
    return ct.active_mask(force), ct.mobilized_mask(force, STATUS)


def test_clusters_linked_by_contacts():
    act, mob = _masks()
    lab = cl.critical_clusters(10, PAIR, act, mob, include=~FIXED)
    assert lab.tolist() == [0, 0, 0, -1, -1, 1, 1, -1, 2, -1]     # numbered by decreasing size
    assert cl.cluster_sizes(lab).tolist() == [3, 2, 1]


def test_clusters_linked_only_by_mobilized_contacts():
    act, mob = _masks()
    lab = cl.critical_clusters(10, PAIR, act, mob, include=~FIXED, link="mobilized")
    # sizes 2, 2, 1, 1: ties ordered by smallest grain index
    assert lab.tolist() == [0, 0, 2, -1, -1, 1, 1, -1, 3, -1]
    with pytest.raises(ValueError):
        cl.critical_clusters(10, PAIR, act, mob, link="forces")


def test_cluster_z_and_n_m_by_hand():
    act, mob = _masks()
    z_i = ct.contact_counts(10, PAIR, act)
    m_i = ct.contact_counts(10, PAIR, mob)
    lab = cl.critical_clusters(10, PAIR, act, mob, include=~FIXED)
    pos = np.arange(20, dtype=float).reshape(10, 2)
    tab = cl.cluster_table(lab, pos, z_i, m_i, theta_deg=0.0)
    # A = {0,1,2}: z_i = 1, 2, 3 -> z = 2; m_i = 1, 1, 1 -> n_m = 3 / 6 = 0.5; dz = 1.5
    # B = {5,6}:   z_i = 1, 1 (6-7 open) -> z = 1; m_i = 1, 1 -> n_m = 0.5; dz = 0.5
    # C = {8}:     z = 1, n_m = 0.5 (its mobilized contact with the fixed grain)
    assert tab["size"].tolist() == [3, 2, 1]
    assert tab["z"].to_numpy() == pytest.approx([2.0, 1.0, 1.0])
    assert tab["n_m"].to_numpy() == pytest.approx([0.5, 0.5, 0.5])
    assert tab["dz"].to_numpy() == pytest.approx([1.5, 0.5, 0.5])
    assert np.isnan(tab["orientation_deg"].iloc[2])          # a single grain has no axis


def test_no_critical_grain_gives_empty_table():
    pair = np.array([[0, 1]])
    lab = cl.critical_clusters(3, pair, np.array([True]), np.array([False]))
    assert (lab == -1).all()
    tab = cl.cluster_table(lab, np.zeros((3, 2)), np.ones(3), np.zeros(3), 5.0)
    assert len(tab) == 0 and "orientation_deg" in tab.columns


@pytest.mark.parametrize("phi, theta, expected", [
    (30.0, 10.0, 70.0),     # |sin(10 - 30)| = sin 20 -> 70 deg
    (90.0, 0.0, 0.0),       # vertical line along gravity
    (0.0, 0.0, 90.0),       # horizontal line, horizontal pile
    (-60.0, 30.0, 0.0),     # line along g = (sin 30, -cos 30), i.e. pointing at -60 deg
    (120.0, 0.0, 30.0),
])
def test_straight_cluster_orientation(phi, theta, expected):
    k = 7
    u = np.array([np.cos(np.deg2rad(phi)), np.sin(np.deg2rad(phi))])
    pos = np.array([5.0, 5.0]) + np.arange(k)[:, None] * u
    pair = np.column_stack([np.arange(k - 1), np.arange(1, k)])
    act = np.ones(k - 1, bool)
    mob = np.ones(k - 1, bool)
    lab = cl.critical_clusters(k, pair, act, mob)
    tab = cl.cluster_table(lab, pos, ct.contact_counts(k, pair, act), ct.contact_counts(k, pair, mob),
                           theta)
    assert len(tab) == 1 and tab["size"].iloc[0] == k
    assert tab["orientation_deg"].iloc[0] == pytest.approx(expected, abs=1e-9)
    # cross-check with the angle between the line and the gravity vector
    g = ct.gravity_vector(theta)
    assert tab["orientation_deg"].iloc[0] == pytest.approx(
        np.rad2deg(np.arccos(min(1.0, abs(u @ g)))), abs=1e-6)
    # a line: the short gyration radius vanishes, the long one is the line's (k^2 - 1)/12 spread
    assert tab["rg_short"].iloc[0] == pytest.approx(0.0, abs=1e-6)
    assert tab["rg_long"].iloc[0] == pytest.approx(np.sqrt((k * k - 1) / 12.0))


def test_isotropic_cluster_has_no_orientation():
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])     # a square ring
    pair = np.array([[0, 1], [1, 2], [2, 3], [0, 3]])
    act = mob = np.ones(4, bool)
    lab = cl.critical_clusters(4, pair, act, mob)
    tab = cl.cluster_table(lab, pos, np.full(4, 2), np.full(4, 2), 12.0)
    assert np.isnan(tab["orientation_deg"].iloc[0])
