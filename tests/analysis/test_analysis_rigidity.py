"""Rigid clusters by the (3,3) pebble game: hand-made networks with known answers, the generic
body-bar rigidity matrix (Tay's theorem) on random multigraphs and on smoke-run frames, the
matrix at the disks' actual geometry, and properties of the counting.

Counting used in the docstrings: B bodies (the ground, i.e. fixed grains + walls, is one of them),
3 B degrees of freedom, I independent bars; floppy modes = 3 B - I - 3. A sticking contact is 2
bars, a sliding one 1 bar. A set of k bodies is rigid when it spans 3 k - 3 independent bars.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tiltpile.analysis import contacts as ct
from tiltpile.analysis import rigidity as rg
from tiltpile.analysis.observables import frame_contacts

import rigidity_oracles as oracles

SQ3 = np.sqrt(3.0)
STICK, SLIDE = 1, 2


def _masks(status):
    """active and mobilized masks of contacts with the given status (0 open, 1 stick, 2 slide)."""
    status = np.asarray(status, np.int8)
    force = np.column_stack([(status > 0).astype(float), np.zeros(len(status))])
    return ct.active_mask(force), ct.mobilized_mask(force, status)


def _rigid(pair, status, n, fixed=None, min_contacts=0, exclude=None):
    pair = np.asarray(pair).reshape(-1, 2)
    fixed = np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool)
    act, mob = _masks(status)
    return rg.rigid_clusters(n, pair, act, mob, fixed, exclude=exclude, min_contacts=min_contacts)


def _matrix_counts(pair, status, position, radius, box_length, fixed=None, min_contacts=0,
                   seed=0):
    """(pebble game, generic matrix, actual-geometry matrix) floppy modes of a frame, and whether
    the generic matrix's clusters equal the pebble game's (the generic matrix in floating point
    and mod p must agree on both)."""
    pair = np.asarray(pair).reshape(-1, 2)
    n = len(radius)
    fixed = np.zeros(n, bool) if fixed is None else np.asarray(fixed, bool)
    act, mob = _masks(status)
    fw = rg.body_bar_framework(n, pair, act, mob, fixed, min_contacts=min_contacts)
    pg = rg.pebble_game(fw.n_bodies, fw.bar_a, fw.bar_b)
    p, u = oracles.generic_geometry(len(fw.bar_a), seed)
    mg = oracles.rigidity_matrix(fw.n_bodies, fw.bar_a, fw.bar_b, p, u)
    same = np.array_equal(rg.canonical_labels(oracles.matrix_rigid_clusters(mg)), pg.cluster)
    exact_floppy, exact_cluster = oracles.exact_generic_rigidity(fw.n_bodies, fw.bar_a, fw.bar_b, seed)
    assert exact_floppy == oracles.matrix_floppy_modes(mg)
    assert np.array_equal(exact_cluster, oracles.matrix_rigid_clusters(mg))
    p, u, c = oracles.contact_geometry(fw, pair, position, radius, box_length)
    ma = oracles.rigidity_matrix(fw.n_bodies, fw.bar_a, fw.bar_b, p, u, c)
    return pg.n_floppy, oracles.matrix_floppy_modes(mg), oracles.matrix_floppy_modes(ma), same


def _same_partition(a, b):
    return np.array_equal(rg.canonical_labels(a), rg.canonical_labels(b))


# ----------------------------------------------------------------------------------------------
# hand-made networks


@pytest.mark.parametrize("status, floppy", [(STICK, 1), (SLIDE, 2)])
def test_single_grain_on_the_floor(status, floppy):
    """One grain on the floor. Sticking: B = 2 (ground, grain), 2 bars -> 6 - 2 - 3 = 1 floppy
    mode (rolling about the contact point). Sliding: 1 bar -> 2 (rolling and sliding). The grain
    is not rigid with the ground: its own cluster of size 1, the contact a floppy bond. The actual
    geometry has the same count (nothing special about one contact)."""
    r = _rigid([[0, -1]], [status], 1)
    assert (r.n_bodies, r.n_bars, r.n_redundant, r.n_floppy) == (2, 3 - status, 0, floppy)
    assert r.grain_cluster.tolist() == [1]
    assert r.bond_cluster.tolist() == [rg.FLOPPY_BOND]
    assert r.cluster_size.tolist() == [0, 1]          # the ground's cluster holds no mobile grain
    assert (r.largest, r.largest_size) == (1, 1)
    assert not rg.spans(r, np.array([True]))
    counts = _matrix_counts([[0, -1]], [status], np.array([[1.0, 0.5]]), np.array([0.5]), 4.0)
    assert counts == (floppy, floppy, floppy, True)


def test_a_grain_with_one_contact_is_a_rattler_by_default():
    """With the z-counting rattler rule (fewer than 2 active contacts) the grain is left out:
    only the ground remains (B = 1, no bar, 3 - 0 - 3 = 0 floppy modes)."""
    r = _rigid([[0, -1]], [STICK], 1, min_contacts=2)
    assert (r.n_left_out, r.n_rattlers, r.n_bodies, r.n_bars, r.n_floppy) == (1, 1, 1, 0, 0)
    assert r.grain_cluster.tolist() == [rg.NOT_IN_FRAMEWORK]
    assert r.bond_cluster.tolist() == [rg.NOT_IN_FRAMEWORK]


def test_grain_in_a_corner():
    """A grain touching the floor and the left wall, both sticking: 4 bars between the grain and
    the ground, at most 3 independent -> 1 redundant, 6 - 3 - 3 = 0 floppy modes, the grain in
    the ground's cluster. Both sliding: 2 bars -> 1 floppy mode (rolling out of the corner), the
    grain its own cluster. Actual geometry: the same counts (sticking: v_y = 0, v_x + r w = 0,
    v_x = 0, v_y - r w = 0 pin it; sliding: v_x = v_y = 0 leave the spin w)."""
    pair, pos, rad = [[0, -1], [0, -2]], np.array([[0.5, 0.5]]), np.array([0.5])
    r = _rigid(pair, [STICK, STICK], 1)
    assert (r.n_bars, r.n_redundant, r.n_floppy) == (4, 1, 0)
    assert r.grain_cluster.tolist() == [rg.GROUND]
    assert r.bond_cluster.tolist() == [rg.GROUND, rg.GROUND]
    assert rg.spans(r, np.array([True]))
    assert _matrix_counts(pair, [STICK, STICK], pos, rad, 4.0) == (0, 0, 0, True)
    r = _rigid(pair, [SLIDE, SLIDE], 1)
    assert (r.n_bars, r.n_redundant, r.n_floppy) == (2, 0, 1)
    assert r.grain_cluster.tolist() == [1]
    assert _matrix_counts(pair, [SLIDE, SLIDE], pos, rad, 4.0) == (1, 1, 1, True)


def test_a_grain_sliding_on_three_walls_spins_at_its_actual_geometry():
    """A grain of diameter 1 in a box of length 1, sliding on the floor and both walls: 3 normal
    bars. Generic: 3 independent bars pin the grain to the ground (0 floppy modes, one cluster).
    Actual geometry: the three normals pass through its centre, the spin is free (1 floppy mode).
    The special position only adds floppy modes, never removes them."""
    pair = [[0, -1], [0, -2], [0, -3]]
    r = _rigid(pair, [SLIDE] * 3, 1)
    assert (r.n_floppy, r.grain_cluster.tolist()) == (0, [rg.GROUND])
    counts = _matrix_counts(pair, [SLIDE] * 3, np.array([[0.5, 0.5]]), np.array([0.5]), 1.0)
    assert counts == (0, 0, 1, True)


TRIANGLE = np.array([[1.0, 0.5], [2.0, 0.5], [1.5, 0.5 + SQ3 / 2]])
TRIANGLE_PAIRS = [[0, 1], [0, 2], [1, 2]]


def test_free_triangle_of_sticking_grains_is_one_rigid_cluster():
    """Three grains touching pairwise, sticking, touching nothing else: B = 4, 6 bars, all
    independent (3 k - 3 = 6 for k = 3) -> 12 - 6 - 3 = 3 floppy modes, the triangle's rigid motion
    relative to the ground. One cluster of 3 grains, the ground alone (size 0)."""
    r = _rigid(TRIANGLE_PAIRS, [STICK] * 3, 3)
    assert (r.n_bodies, r.n_bars, r.n_redundant, r.n_floppy) == (4, 6, 0, 3)
    assert r.grain_cluster.tolist() == [1, 1, 1]
    assert r.bond_cluster.tolist() == [1, 1, 1]
    assert r.cluster_size.tolist() == [0, 3]
    assert (r.largest, r.largest_size) == (1, 3)
    assert not rg.spans(r, np.ones(3, bool))


def test_triangle_on_the_floor_is_rigid_with_the_ground(contacts_factory):
    """The triangle with its two bottom grains sticking on the floor: B = 4, 6 + 4 = 10 bars,
    3 B - 3 = 9 independent -> 1 redundant, 0 floppy modes; everything is the ground's cluster, and
    it spans (the top grain is a surface grain). Actual geometry: 0 as well."""
    pair = contacts_factory(TRIANGLE, np.full(3, 0.5), 4.0)
    assert sorted(map(tuple, pair.tolist())) == [(0, -1), (0, 1), (0, 2), (1, -1), (1, 2)]
    status = [STICK] * len(pair)
    r = _rigid(pair, status, 3, min_contacts=2)
    assert (r.n_left_out, r.n_bodies, r.n_bars, r.n_redundant, r.n_floppy) == (0, 4, 10, 1, 0)
    assert r.grain_cluster.tolist() == [0, 0, 0]
    assert r.bond_cluster.tolist() == [0] * 5
    assert (r.largest, r.largest_size) == (rg.GROUND, 3)
    assert rg.spans(r, np.array([False, False, True]))
    assert _matrix_counts(pair, status, TRIANGLE, np.full(3, 0.5), 4.0) == (0, 0, 0, True)


@pytest.mark.parametrize("status, per_grain", [(STICK, 1), (SLIDE, 2)])
def test_chain_hanging_from_a_wall(status, per_grain):
    """k = 5 grains in a row, the first touching the left wall, neighbours touching: B = k + 1,
    k contacts, no cycle, so every bar is independent. Sticking: 2 k bars -> 3 (k + 1) - 2 k - 3 =
    k floppy modes; sliding: k bars -> 2 k. No two bodies are rigid together (a pair needs 3
    bars): every grain is its own cluster and every contact a floppy bond. Actual geometry: equal
    (the normals all lie on one line, but each grain has at most 2 of them)."""
    k = 5
    pair = [[0, -2]] + [[g, g + 1] for g in range(k - 1)]
    r = _rigid(pair, [status] * k, k)
    assert (r.n_bodies, r.n_redundant, r.n_floppy) == (k + 1, 0, per_grain * k)
    assert r.grain_cluster.tolist() == list(range(1, k + 1))
    assert r.cluster_size.tolist() == [0] + [1] * k
    assert (r.bond_cluster == rg.FLOPPY_BOND).all()
    pos = np.column_stack([np.arange(k) + 0.5, np.full(k, 5.0)])
    counts = _matrix_counts(pair, [status] * k, pos, np.full(k, 0.5), 10.0)
    assert counts == (per_grain * k, per_grain * k, per_grain * k, True)


def test_ring_of_four_sticking_grains_is_floppy():
    """A square ring of 4 grains, neighbours sticking: B = 5 (the ground untouched), 8 bars, all
    independent (a path of m grains spans 2 (m - 1) <= 3 m - 3, the ring 8 <= 9) -> 15 - 8 - 3 = 4
    floppy modes: 3 rigid motions and 1 internal one (the ring shears). No rigid pair: 4
    singleton clusters. Actual geometry: 4 as well."""
    pos = np.array([[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]])
    pair = [[0, 1], [1, 2], [2, 3], [0, 3]]
    r = _rigid(pair, [STICK] * 4, 4, min_contacts=2)
    assert (r.n_bodies, r.n_bars, r.n_redundant, r.n_floppy) == (5, 8, 0, 4)
    assert r.cluster_size.tolist() == [0, 1, 1, 1, 1]
    assert (r.bond_cluster == rg.FLOPPY_BOND).all()
    assert _matrix_counts(pair, [STICK] * 4, pos, np.full(4, 0.5), 10.0) == (4, 4, 4, True)


def test_hexagonal_flower_is_rigid(contacts_factory):
    """A grain with its 6 hexagonal neighbours, every contact sticking (6 spokes + 6 rim
    contacts = 12): B = 8, 24 bars, 3 * 7 - 3 = 18 independent among the 7 grains -> 6
    redundant, 24 - 18 - 3 = 3 floppy modes (the flower moves rigidly, nothing holds it).
    One cluster of 7; every bond in it."""
    ang = np.arange(6) * np.pi / 3
    pos = np.vstack([[5.0, 5.0], np.column_stack([5.0 + np.cos(ang), 5.0 + np.sin(ang)])])
    pair = contacts_factory(pos, np.full(7, 0.5), 10.0)
    assert len(pair) == 12 and (pair[:, 1] >= 0).all()
    r = _rigid(pair, [STICK] * 12, 7, min_contacts=2)
    assert (r.n_bodies, r.n_bars, r.n_redundant, r.n_floppy) == (8, 24, 6, 3)
    assert r.grain_cluster.tolist() == [1] * 7
    assert (r.bond_cluster == 1).all()
    assert _matrix_counts(pair, [STICK] * 12, pos, np.full(7, 0.5), 10.0) == (3, 3, 3, True)


def _two_blocks(contacts_factory):
    """Block A: TRIANGLE on the floor (grains 0-2). Block B: a rhombus of 4 grains (3-6) whose
    grain 3 touches grain 2 only. Returns position, pair; grain-grain contacts inside the blocks
    stick, the link 2-3 slides."""
    p = TRIANGLE[2] + np.array([SQ3 / 2, 0.5])
    rh = p + np.array([[0.0, 0.0], [1.0, 0.0], [0.5, SQ3 / 2], [1.5, SQ3 / 2]])
    pos = np.vstack([TRIANGLE, rh])
    pair = contacts_factory(pos, np.full(7, 0.5), 10.0)
    return pos, pair


def test_two_rigid_blocks_joined_by_one_sliding_contact(contacts_factory):
    """Block A (triangle on the floor: 10 bars, 1 redundant) is rigid with the ground; block B
    (rhombus, 5 sticking contacts = 10 bars, 3 * 4 - 3 = 9 independent, 1 redundant) is rigid on
    its own; one sliding contact (1 bar) joins them. B = 8, 21 bars, 19 independent ->
    24 - 19 - 3 = 2 floppy modes (B pivots and slides on A). Two clusters: the ground's (3 grains)
    and B's (4 grains, the largest, which does not contain the ground, so the pile is not spanned
    by its largest cluster, while the ground's cluster does reach the surface grain 2). The
    sliding bond joins two clusters: FLOPPY_BOND."""
    pos, pair = _two_blocks(contacts_factory)
    keys = sorted(map(tuple, pair.tolist()))
    assert keys == [(0, -1), (0, 1), (0, 2), (1, -1), (1, 2), (2, 3),
                    (3, 4), (3, 5), (4, 5), (4, 6), (5, 6)]
    status = np.where([tuple(p) == (2, 3) for p in pair.tolist()], SLIDE, STICK)
    r = _rigid(pair, status, 7, min_contacts=2)
    assert (r.n_bodies, r.n_bars, r.n_redundant, r.n_floppy) == (8, 21, 2, 2)
    assert r.grain_cluster.tolist() == [0, 0, 0, 1, 1, 1, 1]
    assert r.cluster_size.tolist() == [3, 4]
    assert (r.largest, r.largest_size) == (1, 4)
    assert r.bond_cluster[status == SLIDE].tolist() == [rg.FLOPPY_BOND]
    assert (r.bond_cluster[status == STICK] >= 0).all()
    top = np.zeros(7, bool)
    top[[2, 5, 6]] = True
    assert not rg.spans(r, top)
    assert rg.spans(r, top, label=rg.GROUND)
    assert _matrix_counts(pair, status, pos, np.full(7, 0.5), 10.0) == (2, 2, 2, True)


@pytest.mark.parametrize("links, floppy, n_clusters", [(1, 2, 2), (2, 1, 2), (3, 0, 1)])
def test_blocks_joined_by_more_sliding_contacts(contacts_factory, links, floppy, n_clusters):
    """The same two blocks joined by 1, 2 or 3 sliding contacts (2-3, then 1-4 and 2-5 added as
    network bonds): each independent link removes one of block B's 3 motions relative to A, so
    2, 1, 0 floppy modes; with 3 links (generic) the blocks weld into one cluster of 7 grains,
    the ground's."""
    _, pair = _two_blocks(contacts_factory)
    extra = np.array([[1, 4], [2, 5]])[: links - 1]
    pair = np.vstack([pair, extra])
    status = np.where([tuple(p) in ((2, 3), (1, 4), (2, 5)) for p in pair.tolist()], SLIDE, STICK)
    r = _rigid(pair, status, 7, min_contacts=2)
    assert r.n_floppy == floppy
    assert len(r.cluster_size) == n_clusters
    if n_clusters == 1:
        assert r.grain_cluster.tolist() == [rg.GROUND] * 7
        assert (r.bond_cluster == rg.GROUND).all()


def test_lattice_pile_is_one_spanning_cluster_until_cut(pile_factory, contacts_factory):
    """A triangular pile (10 wide, 8 mobile rows) on a fixed row, every contact sticking: far
    over-constrained, 0 floppy modes, every mobile grain in the ground's cluster, which spans.
    Opening every contact of the top 4 rows with the rows below and with the side walls leaves
    them a floating block: 3 floppy modes (its rigid motion), two clusters of 38 grains each (rows
    1-4 and rows 5-8); the tie goes to the ground's cluster, which holds no surface grain: nothing
    spans."""
    pos, rad, fixed, row = pile_factory(10, 8)
    pair = contacts_factory(pos, rad, 10.0)
    n = len(rad)
    top = ct.top_layer(pos, rad, fixed, 10.0)
    assert set(row[top]) == {8}
    status = np.full(len(pair), STICK)
    r = _rigid(pair, status, n, fixed=fixed, min_contacts=2)
    assert (r.n_floppy, r.n_left_out) == (0, 0)
    assert (r.grain_cluster == rg.GROUND).all()          # mobile and fixed grains alike
    assert r.largest_size == (~fixed).sum()
    assert rg.spans(r, top)
    # contacts inside the ground (fixed-fixed, fixed-wall) give no bar
    ground = fixed[pair[:, 0]] & ((pair[:, 1] < 0) | fixed[np.maximum(pair[:, 1], 0)])
    assert (r.bond_cluster[ground] == rg.NOT_IN_FRAMEWORK).all()
    assert (r.bond_cluster[~ground] == rg.GROUND).all()
    high = row >= 5
    jrow = np.where(pair[:, 1] >= 0, row[np.maximum(pair[:, 1], 0)], -1)
    cut = high[pair[:, 0]] & ((pair[:, 1] < 0) | (jrow < 5))
    cut |= (pair[:, 1] >= 0) & high[np.maximum(pair[:, 1], 0)] & ~high[pair[:, 0]]
    status[cut] = 0
    r = _rigid(pair, status, n, fixed=fixed, min_contacts=2)
    assert r.n_floppy == 3
    assert len(r.cluster_size) == 2
    assert r.cluster_size.tolist() == [(~fixed & ~high).sum(), high.sum()]
    assert (r.grain_cluster[high] == 1).all()
    assert r.largest == rg.GROUND and r.cluster_size[0] == r.cluster_size[1]
    assert not rg.spans(r, top)
    assert not rg.spans(r, top, label=1)           # the top block does not contain the ground
    assert (r.bond_cluster[cut] == rg.NOT_IN_FRAMEWORK).all()


def test_rattlers_exclusions_and_isolated_grains():
    """Grains 0 and 1 touch each other and the floor (kept); 2 touches only 0 and 3 nothing
    (rattlers: left out, their contacts dropped); 4 is excluded by the caller; 5 is fixed (the
    ground; listing it in ``exclude`` changes nothing) and touches 0; 7 touches only 6 (a
    rattler); 6 touches 4 and 7, so it is no rattler, but once their contacts are dropped it has
    none: left out too. All contacts stick. Kept: 0, 1 -> B = 3; bars 2 (0-1) + 4 (floor) + 2
    (0-5) = 8, 3 * 3 - 3 = 6 independent -> 2 redundant, 0 floppy modes, grains 0, 1 and 5 in the
    ground's cluster."""
    pair = [[0, 1], [0, -1], [1, -1], [0, 2], [0, 5], [6, 7], [4, 6], [4, -1], [4, 1]]
    fixed = np.zeros(8, bool)
    fixed[5] = True
    exclude = np.zeros(8, bool)
    exclude[[4, 5]] = True
    r = _rigid(pair, [STICK] * len(pair), 8, fixed=fixed, min_contacts=2, exclude=exclude)
    assert (r.n_bodies, r.n_bars, r.n_redundant, r.n_floppy) == (3, 8, 2, 0)
    assert (r.n_left_out, r.n_rattlers) == (5, 3)     # 2, 3, 4, 6, 7; rattlers 2, 3, 7
    assert r.grain_cluster.tolist() == [0, 0, -1, -1, -1, 0, -1, -1]
    assert r.bond_cluster.tolist() == [0, 0, 0, -1, 0, -1, -1, -1, -1]


def test_rigidity_matrix_row():
    """A bar through p = (1, 0) along u = (0, 1) between bodies centred at (0, 0) and (2, 0):
    row (u_x, u_y, (p - c_a) x u) for a and minus (u_x, u_y, (p - c_b) x u) for b
    = (0, 1, 1, 0, -1, 1): a unit rotation of both bodies about their centres moves their ends of
    the bar the same way."""
    m = oracles.rigidity_matrix(2, [0], [1], [[1.0, 0.0]], [[0.0, 1.0]], [[0.0, 0.0], [2.0, 0.0]])
    assert m.tolist() == [[0.0, 1.0, 1.0, 0.0, -1.0, 1.0]]
    assert oracles.matrix_floppy_modes(np.zeros((0, 6))) == 3
    assert oracles.matrix_floppy_modes(m) == 2


# ----------------------------------------------------------------------------------------------
# the pebble game against the generic rigidity matrix (Tay's theorem)


def random_multigraph(rng, n, reach=(1.1, 1.9), mult=(0, 1, 2, 2, 3)):
    """Bodies at random points (density 1); each pair closer than a random reach gets 0-3 bars,
    shuffled: locally dense, with rigid clusters of many sizes."""
    xy = rng.random((n, 2)) * np.sqrt(n)
    d = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    cand = np.argwhere((d < rng.uniform(*reach)) & np.triu(np.ones((n, n), bool), 1))
    m = rng.choice(mult, len(cand))
    a, b = np.repeat(cand[:, 0], m), np.repeat(cand[:, 1], m)
    flip = rng.random(len(a)) < 0.5
    a, b = np.where(flip, b, a), np.where(flip, a, b)
    perm = rng.permutation(len(a))
    return a[perm], b[perm]


def _tay_check(n, a, b, rng, floats=True):
    """The pebble game against the generic matrix mod p (exact) and, with ``floats``, against a
    random real realization (SVD)."""
    pg = rg.pebble_game(n, a, b)
    n_floppy, cluster = oracles.exact_generic_rigidity(n, a, b, rng)
    assert n_floppy == pg.n_floppy
    assert np.array_equal(cluster, pg.cluster)
    if floats:
        p, u = oracles.generic_geometry(len(a), rng)
        centre = rng.random((n, 2)) * np.sqrt(n)
        m = oracles.rigidity_matrix(n, a, b, p, u, centre)
        ns = oracles.matrix_null_space(m)
        assert ns.shape[1] - 3 == pg.n_floppy == oracles.matrix_floppy_modes(m)
        assert np.array_equal(oracles.matrix_rigid_clusters(m, centre, null_space=ns), pg.cluster)
    return pg


@pytest.mark.parametrize("seed", range(6))
def test_pebble_game_equals_generic_matrix_on_random_multigraphs(seed):
    """Floppy modes and rigid clusters of the pebble game equal those of the generic body-bar
    rigidity matrix (nullity - 3; null-space clusters) on 25 random multigraphs of 2-40 bodies
    per seed (exact; in floating point too up to 20 bodies: larger SVDs are slow on a busy
    machine, and the 150-body gap test below covers them), and on one of 100-300 bodies (exact:
    real realizations of large near-isostatic frameworks can be too ill-conditioned for a fixed
    rank tolerance, see the module docstring)."""
    rng = np.random.default_rng(seed)
    for _ in range(25):
        n = int(rng.integers(2, 41))
        a, b = random_multigraph(rng, n)
        _tay_check(n, a, b, rng, floats=n <= 20)
    n = int(rng.integers(100, 301))
    a, b = random_multigraph(rng, n)
    pg = _tay_check(n, a, b, rng, floats=False)
    assert np.bincount(pg.cluster).max() >= 5            # clusters of some size were tested


def test_null_space_clusters_are_separated_by_a_wide_gap():
    """The null-space cluster test's tolerance sits in a wide gap: on a generic realization
    bodies of one pebble-game cluster differ by < 1e-10, bodies of two clusters by > 1e-3; and
    the floating-point count and clusters of this 150-body multigraph equal the pebble game's."""
    rng = np.random.default_rng(11)
    n = 150
    a, b = random_multigraph(rng, n)
    pg = rg.pebble_game(n, a, b)
    p, u = oracles.generic_geometry(len(a), rng)
    centre = rng.random((n, 2)) * 10
    ns = oracles.matrix_null_space(oracles.rigidity_matrix(n, a, b, p, u, centre))
    x0 = centre.mean(axis=0)
    ell = max(1.0, np.linalg.norm(centre - x0, axis=1).max())
    blk = ns.reshape(n, 3, -1)
    dx, dy = (x0 - centre)[:, :1], (x0 - centre)[:, 1:]
    z = np.concatenate([(blk[:, 0] - blk[:, 2] * dy) / ell, (blk[:, 1] + blk[:, 2] * dx) / ell,
                        blk[:, 2]], axis=1)
    dist = np.linalg.norm(z[:, None] - z[None], axis=2)
    same = pg.cluster[:, None] == pg.cluster[None]
    assert (pg.cluster[:, None] != pg.cluster[None]).any() and np.bincount(pg.cluster).max() > 1
    assert dist[same].max() < 1e-10
    assert dist[~same].min() > 1e-3
    assert ns.shape[1] - 3 == pg.n_floppy
    m = oracles.rigidity_matrix(n, a, b, p, u, centre)
    assert np.array_equal(oracles.matrix_rigid_clusters(m, centre, null_space=ns), pg.cluster)


def test_redundant_bars_lie_inside_a_cluster_independent_ones_need_not():
    """Checks the module's claim on random multigraphs: both ends of every redundant bar are in
    one cluster; some independent bars join two clusters."""
    rng = np.random.default_rng(5)
    joins = 0
    for _ in range(30):
        n = int(rng.integers(5, 60))
        a, b = random_multigraph(rng, n)
        pg = rg.pebble_game(n, a, b)
        c = pg.cluster
        assert (c[a[~pg.independent]] == c[b[~pg.independent]]).all()
        joins += int((c[a[pg.independent]] != c[b[pg.independent]]).sum())
    assert joins > 0


# ----------------------------------------------------------------------------------------------
# real frames: a smoke run


@pytest.fixture(scope="module")
def smoke_frames(smoke_run):
    """Four frames of the smoke run: the first, the one with most sliding contacts, the middle
    one and the last, each as (framework, pair, position) with the arrays the observables use."""
    from tiltpile.store import open_run

    out = []
    with open_run(smoke_run[0]) as run:
        n_slide = [int((run.contacts(k)[2] == 2).sum()) for k in range(run.n_frames)]
        picks = sorted({0, int(np.argmax(n_slide)), run.n_frames // 2, run.n_frames - 1})
        for k in picks:
            pos = run.position(k)
            pair, force, status = run.contacts(k)
            fc = frame_contacts(run.radius, run.fixed, run.box_length, pos, pair, force, status)
            fw = rg.body_bar_framework(len(run.radius), fc["pair"], fc["active"], fc["mobilized"],
                                       run.fixed)
            out.append((k, fw, fc, pos, run.radius, run.fixed, run.box_length))
    return out


def test_smoke_frames_pebble_game_equals_generic_matrix(smoke_frames):
    """On real frames the pebble game's floppy modes and clusters equal the generic matrix's
    (exact, mod p; in floating point a draw can be too ill-conditioned for a fixed tolerance:
    module docstring), and :func:`rigid_clusters` reports the same count."""
    assert any(f[2]["mobilized"].any() for f in smoke_frames)
    for k, fw, fc, pos, radius, fixed, box_length in smoke_frames:
        assert fw.n_bodies > 150
        pg = rg.pebble_game(fw.n_bodies, fw.bar_a, fw.bar_b)
        n_floppy, cluster = oracles.exact_generic_rigidity(fw.n_bodies, fw.bar_a, fw.bar_b, k)
        assert n_floppy == pg.n_floppy, f"frame {k}"
        assert np.array_equal(cluster, pg.cluster), f"frame {k}"
        r = rg.rigid_clusters(len(radius), fc["pair"], fc["active"], fc["mobilized"], fixed)
        assert (r.n_floppy, r.n_bodies, r.n_bars) == (pg.n_floppy, fw.n_bodies, len(fw.bar_a))
        assert r.cluster_size.sum() == (r.grain_cluster[~fixed] >= 0).sum()


def test_smoke_frames_actual_geometry_has_at_least_the_generic_floppy_modes(smoke_frames):
    """The matrix at the disks' actual geometry (normal bars through the centres, tangential bars
    at the contact points) is a special realization: its rank can only be lower, its floppy modes
    at least the pebble game's. Every extra mode must move something: at least one grain is not
    rigid with its generic cluster. (How often it differs: see the issue's report.)"""
    for k, fw, fc, pos, radius, fixed, box_length in smoke_frames:
        pg = rg.pebble_game(fw.n_bodies, fw.bar_a, fw.bar_b)
        p, u, c = oracles.contact_geometry(fw, fc["pair"], pos, radius, box_length)
        m = oracles.rigidity_matrix(fw.n_bodies, fw.bar_a, fw.bar_b, p, u, c)
        actual = oracles.matrix_floppy_modes(m)
        assert actual >= pg.n_floppy, f"frame {k}"


def test_contact_geometry_puts_bars_where_disks_touch(smoke_frames):
    """Normal bars run along the line of centres (walls: their normals), tangential bars are
    perpendicular to them, and both pass through a point on the segment between the centres at
    distance r_i - delta / 2 from grain i."""
    k, fw, fc, pos, radius, fixed, box_length = smoke_frames[0]
    p, u, c = oracles.contact_geometry(fw, fc["pair"], pos, radius, box_length)
    pair = fc["pair"][fw.bar_contact]
    i, j = pair[:, 0], pair[:, 1]
    gg = j >= 0
    normal = fw.bar_kind == rg.NORMAL
    branch = pos[np.maximum(j, 0)] - pos[i]
    branch /= np.linalg.norm(branch, axis=1)[:, None]
    cross = branch[:, 0] * u[:, 1] - branch[:, 1] * u[:, 0]
    dot = (branch * u).sum(axis=1)
    assert np.allclose(np.abs(cross[gg & normal]), 0, atol=1e-12)
    assert np.allclose(dot[gg & normal], 1)
    assert np.allclose(dot[gg & ~normal], 0, atol=1e-12)
    d = np.linalg.norm(p - pos[i], axis=1)
    assert np.allclose(d, radius[i], atol=1e-4)
    floor = j == ct.WALL_FLOOR
    assert np.allclose(u[floor & normal], [0.0, -1.0])
    kept = fw.body > 0
    assert np.array_equal(c[fw.body[kept]], pos[kept])


# ----------------------------------------------------------------------------------------------
# properties


@st.composite
def multigraphs(draw, max_bodies=12, max_bars=40):
    n = draw(st.integers(1, max_bodies))
    if n == 1:
        return 1, np.zeros(0, np.int64), np.zeros(0, np.int64)
    pairs = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1))
                          .filter(lambda t: t[0] != t[1]), max_size=max_bars))
    a = np.array([t[0] for t in pairs], np.int64)
    b = np.array([t[1] for t in pairs], np.int64)
    return n, a, b


def _coarser_or_equal(fine, coarse):
    """Every part of ``fine`` lies inside one part of ``coarse``."""
    return all(len(set(coarse[fine == c])) == 1 for c in np.unique(fine))


@settings(max_examples=200, deadline=None)
@given(g=multigraphs(), extra=st.tuples(st.integers(0, 11), st.integers(0, 11)))
def test_adding_a_bar_never_adds_a_floppy_mode(g, extra):
    """A bar removes at most one floppy mode and never adds one; rigid clusters can only merge."""
    n, a, b = g
    x, y = extra[0] % n, extra[1] % n
    before = rg.pebble_game(n, a, b)
    after = rg.pebble_game(n, np.r_[a, x], np.r_[b, y])
    assert before.n_floppy - 1 <= after.n_floppy <= before.n_floppy
    assert _coarser_or_equal(before.cluster, after.cluster)


@settings(max_examples=200, deadline=None)
@given(g=multigraphs(), seed=st.integers(0, 2**32 - 1))
def test_bar_order_changes_neither_count_nor_clusters(g, seed):
    """Shuffling the bars (and swapping their ends) leaves the floppy modes, the number of
    redundant bars and the clusters (as a partition) unchanged."""
    n, a, b = g
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(a))
    flip = rng.random(len(a)) < 0.5
    a2, b2 = np.where(flip, b, a)[perm], np.where(flip, a, b)[perm]
    one, two = rg.pebble_game(n, a, b), rg.pebble_game(n, a2, b2)
    assert one.n_floppy == two.n_floppy
    assert one.independent.sum() == two.independent.sum()
    assert np.array_equal(one.cluster, two.cluster)


@settings(max_examples=150, deadline=None)
@given(g=multigraphs(), seed=st.integers(0, 2**32 - 1))
def test_small_multigraphs_agree_with_the_generic_matrix(g, seed):
    """Tay's theorem on arbitrary small multigraphs (parallel bars, disconnected pieces)."""
    n, a, b = g
    _tay_check(n, a, b, np.random.default_rng(seed))
