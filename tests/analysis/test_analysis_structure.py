"""Packing fraction and fabric against configurations whose answers are known."""

import numpy as np
import pytest

from tiltpile.analysis.structure import bulk_window, fabric, packing_fraction, surface_tilt_deg


def test_one_disk_covers_pi_r2_of_the_window():
    # a disk of radius 1 in a 4 x 4 window: pi / 16, within the grid's spacing^2 error
    phi = packing_fraction([[2.0, 2.0]], [1.0], (0.0, 4.0, 0.0, 4.0), spacing=0.01)
    assert phi == pytest.approx(np.pi / 16, abs=2e-4)


def test_disks_cut_by_the_window_count_only_inside():
    # a disk centred on the window's edge covers half a disk
    phi = packing_fraction([[0.0, 2.0]], [1.0], (0.0, 4.0, 0.0, 4.0), spacing=0.01)
    assert phi == pytest.approx(np.pi / 2 / 16, abs=3e-4)


def test_square_lattice_of_touching_disks():
    # touching disks of radius 1/2 on a unit square lattice cover pi/4 of any window of whole
    # cells; the lattice is shifted off the grid's points (a grid aligned with every disk's
    # centre counts each disk's boundary points alike: a systematic error of ~0.5% at 0.02 d,
    # which positions of real piles do not share)
    xs, ys = np.meshgrid(np.arange(-1, 12) + 0.5 + 0.00713, np.arange(-1, 12) + 0.5 + 0.00291)
    pos = np.stack([xs.ravel(), ys.ravel()], axis=1)
    phi = packing_fraction(pos, np.full(len(pos), 0.5), (0.0, 10.0, 0.0, 10.0), spacing=0.02)
    assert phi == pytest.approx(np.pi / 4, abs=1e-3)


def test_overlapping_disks_are_not_counted_twice():
    one = packing_fraction([[2.0, 2.0]], [1.0], (0.0, 4.0, 0.0, 4.0), spacing=0.01)
    two = packing_fraction([[2.0, 2.0], [2.0, 2.0]], [1.0, 1.0], (0.0, 4.0, 0.0, 4.0), spacing=0.01)
    assert two == one


def test_bad_window_and_spacing_are_refused():
    with pytest.raises(ValueError, match="empty window"):
        packing_fraction([[0.0, 0.0]], [1.0], (1.0, 1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="spacing"):
        packing_fraction([[0.0, 0.0]], [1.0], (0.0, 1.0, 0.0, 1.0), spacing=0.0)


def test_fabric_of_vertical_contacts_is_fully_anisotropic_along_y():
    pos = np.array([[0.0, 0.0], [0.0, 1.0], [0.0, 2.0]])
    pair = np.array([[0, 1], [1, 2], [0, -1]])  # the wall contact is left out
    f = fabric(pair, pos, np.array([True, True, True]))
    assert f["n_contacts"] == 2
    assert f["anisotropy"] == pytest.approx(2.0)
    assert f["major_deg"] == pytest.approx(0.0, abs=1e-9)


def test_fabric_of_a_square_lattice_is_isotropic_and_of_a_tilted_pair_points_along_it():
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    pair = np.array([[0, 1], [0, 2], [1, 3], [2, 3]])
    assert fabric(pair, pos, np.ones(4, bool))["anisotropy"] == pytest.approx(0.0, abs=1e-12)
    pos2 = np.array([[0.0, 0.0], [np.sin(np.radians(30)), np.cos(np.radians(30))]])
    f = fabric(np.array([[0, 1]]), pos2, np.array([True]))
    assert f["major_deg"] == pytest.approx(30.0)
    # inactive contacts and unselected grains are left out
    assert fabric(pair, pos, np.zeros(4, bool))["n_contacts"] == 0
    sel = np.array([True, False, False, False])
    assert fabric(pair, pos, np.ones(4, bool), select=sel)["n_contacts"] == 2


def test_bulk_window_lies_inside_the_pile():
    # a 30 x 12 lattice pile on a row of fixed grains
    xs, ys = np.meshgrid(np.arange(30) + 0.5, np.arange(12) + 0.5)
    pos = np.stack([xs.ravel(), ys.ravel()], axis=1)
    fixed = pos[:, 1] < 1.0
    x0, x1, y0, y1 = bulk_window(pos, np.full(len(pos), 0.5), fixed, 30.0, margin=3.0)
    assert (x0, x1) == (3.0, 27.0)
    assert y0 == pytest.approx(4.0) and y1 == pytest.approx(11.5 - 3.0)
    with pytest.raises(ValueError, match="no window"):
        bulk_window(pos, np.full(len(pos), 0.5), fixed, 30.0, margin=6.0)


def test_surface_tilt_of_a_tilted_layer():
    """A row of grains whose tops rise by 1 d over 10 d: tilt atan(0.1), towards x = L."""
    x = np.arange(0.5, 30.0, 1.0)
    pos = np.stack([x, 5.0 + 0.1 * x], axis=1)
    r = np.full(len(x), 0.5)
    tilt = surface_tilt_deg(pos, r, np.zeros(len(x), bool), 30.0)
    assert tilt == pytest.approx(np.degrees(np.arctan(0.1)))
    assert np.isnan(surface_tilt_deg(pos[:1], r[:1], np.zeros(1, bool), 30.0))  # one grain
