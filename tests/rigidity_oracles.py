"""Test oracles of the rigid-cluster count (:mod:`tiltpile.analysis.rigidity`): the body-bar
rigidity matrix in floating point (generic or at the disks' actual geometry) and the generic matrix
in exact arithmetic mod a prime. Only the tests use them; the module docstring of
:mod:`tiltpile.analysis.rigidity` says what they check and what they found.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee

from tiltpile.analysis.contacts import WALL_FLOOR, WALL_LEFT, WALL_RIGHT
from tiltpile.analysis.rigidity import GROUND, TANGENTIAL, Framework, canonical_labels


# ----------------------------------------------------------------------------------------------
# the rigidity matrix (the independent check)


def rigidity_matrix(n_bodies: int, bar_a: np.ndarray, bar_b: np.ndarray, point: np.ndarray,
                    direction: np.ndarray, centre: np.ndarray | None = None) -> np.ndarray:
    """Rigidity matrix (B, 3 n_bodies) of a body-bar framework (module docstring).

    bar_a, bar_b (B,) bodies; point (B, 2) where each bar acts, direction (B, 2) its unit
    direction; centre (n_bodies, 2) each body's reference point (None: the origin for all; the
    rank does not depend on it). Columns 3 b, 3 b + 1, 3 b + 2 = (v_x, v_y, omega) of body b.
    """
    bar_a = np.asarray(bar_a, dtype=np.int64).ravel()
    bar_b = np.asarray(bar_b, dtype=np.int64).ravel()
    p = np.asarray(point, dtype=float).reshape(-1, 2)
    u = np.asarray(direction, dtype=float).reshape(-1, 2)
    c = np.zeros((n_bodies, 2)) if centre is None else np.asarray(centre, dtype=float)
    nb = bar_a.size
    m = np.zeros((nb, 3 * n_bodies))
    rows = np.arange(nb)
    for body, sign in ((bar_a, 1.0), (bar_b, -1.0)):
        r = p - c[body]
        np.add.at(m, (rows, 3 * body), sign * u[:, 0])
        np.add.at(m, (rows, 3 * body + 1), sign * u[:, 1])
        np.add.at(m, (rows, 3 * body + 2), sign * (r[:, 0] * u[:, 1] - r[:, 1] * u[:, 0]))
    return m


def generic_geometry(n_bars: int, rng=None) -> tuple[np.ndarray, np.ndarray]:
    """A generic realization: each bar's point uniform in the unit square, its direction uniform
    on the circle. Returns point (B, 2), direction (B, 2)."""
    rng = np.random.default_rng(rng)
    point = rng.random((n_bars, 2))
    phi = rng.random(n_bars) * 2.0 * np.pi
    return point, np.column_stack([np.cos(phi), np.sin(phi)])


def contact_geometry(framework: Framework, pair: np.ndarray, position: np.ndarray,
                     radius: np.ndarray, box_length: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bars where the disks touch: point, direction (B, 2) and body centres (n_bodies, 2).

    A contact's unit normal n points from grain i to its partner (grain j, or the floor (0, -1),
    left wall (-1, 0), right wall (1, 0)); its point is x_i + (r_i - delta / 2) n, the middle of
    the overlap delta (or of the gap). The normal bar runs along n, the tangential bar along
    (-n_y, n_x) through the same point. Body centres: the grains' centres; the ground's at
    (L / 2, 0) (any point would do).
    """
    pair = np.asarray(pair, dtype=np.int64).reshape(-1, 2)
    position = np.asarray(position, dtype=float).reshape(-1, 2)
    radius = np.asarray(radius, dtype=float)
    c = framework.bar_contact
    i, j = pair[c, 0], pair[c, 1]
    xi, ri = position[i], radius[i]
    jj = np.maximum(j, 0)
    d = position[jj] - xi
    dist = np.linalg.norm(d, axis=1)
    n = d / np.where(dist > 0, dist, 1.0)[:, None]
    gap_dist = dist.copy()
    partner_r = radius[jj].copy()
    for wall, normal, distance in ((WALL_FLOOR, (0.0, -1.0), xi[:, 1]),
                                   (WALL_LEFT, (-1.0, 0.0), xi[:, 0]),
                                   (WALL_RIGHT, (1.0, 0.0), box_length - xi[:, 0])):
        w = j == wall
        n[w] = normal
        gap_dist[w] = distance[w]
        partner_r[w] = 0.0
    delta = ri + partner_r - gap_dist
    point = xi + (ri - 0.5 * delta)[:, None] * n
    t = np.column_stack([-n[:, 1], n[:, 0]])
    direction = np.where((framework.bar_kind == TANGENTIAL)[:, None], t, n)
    centre = np.zeros((framework.n_bodies, 2))
    centre[GROUND] = (0.5 * box_length, 0.0)
    kept = framework.body > GROUND
    centre[framework.body[kept]] = position[kept]
    return point, direction, centre


def matrix_null_space(matrix: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis (3 n_bodies, k) of a rigidity matrix's null space (full SVD; singular
    values at most ``rtol`` times the largest count as zero)."""
    m = np.asarray(matrix, dtype=float)
    ncol = m.shape[1]
    if m.shape[0] == 0 or not np.any(m):
        return np.eye(ncol)
    _, s, vt = np.linalg.svd(m, full_matrices=True)
    rank = int(np.sum(s > rtol * s[0]))
    return vt[rank:].T


def matrix_floppy_modes(matrix: np.ndarray, rtol: float = 1e-9) -> int:
    """Floppy modes of a body-bar rigidity matrix: its nullity (singular values at most ``rtol``
    times the largest count as zero) minus the 3 rigid motions of the plane."""
    m = np.asarray(matrix, dtype=float)
    if m.shape[0] == 0 or not np.any(m):
        return m.shape[1] - 3
    s = np.linalg.svd(m, compute_uv=False)
    return m.shape[1] - int(np.sum(s > rtol * s[0])) - 3


def matrix_rigid_clusters(matrix: np.ndarray, centre: np.ndarray | None = None,
                          rtol: float = 1e-9, atol: float = 1e-6,
                          null_space: np.ndarray | None = None) -> np.ndarray:
    """Rigid clusters read from the null space of a rigidity matrix (B, 3 n_bodies).

    Two bodies are in one cluster when every null-space motion moves them as one rigid body:
    equal rotation rates and equal velocity fields, compared at a common point x0 (the centres'
    mean) as Z_b = (V_b(x0) / l, omega_b) with l the centres' largest distance from x0 (at least
    1); bodies whose Z differ by at most ``atol`` (Euclidean norm over an orthonormal null-space
    basis) are grouped, greedily from the lowest body. centre (n_bodies, 2): the reference points
    the matrix was built with (None: the origin); null_space: :func:`matrix_null_space` of the
    matrix when already at hand. Returns (n_bodies,) labels, numbered by smallest body (as
    :func:`pebble_game`).

    On generic realizations within-cluster differences come out below 1e-11 and differences
    between clusters above 1e-2 (tests/analysis/test_analysis_rigidity.py).
    """
    ns = matrix_null_space(matrix, rtol) if null_space is None else np.asarray(null_space)
    nbody = ns.shape[0] // 3
    c = np.zeros((nbody, 2)) if centre is None else np.asarray(centre, dtype=float)
    x0 = c.mean(axis=0)
    ell = max(1.0, float(np.max(np.linalg.norm(c - x0, axis=1))))
    blk = ns.reshape(nbody, 3, -1)
    vx, vy, om = blk[:, 0], blk[:, 1], blk[:, 2]
    dx = (x0 - c)[:, 0:1]
    dy = (x0 - c)[:, 1:2]
    z = np.concatenate([(vx - om * dy) / ell, (vy + om * dx) / ell, om], axis=1)
    label = np.full(nbody, -1, dtype=np.int64)
    k = 0
    for b in range(nbody):
        if label[b] >= 0:
            continue
        free = np.flatnonzero(label < 0)
        same = free[np.linalg.norm(z[free] - z[b], axis=1) <= atol]
        label[same] = k
        k += 1
    return label


# ----------------------------------------------------------------------------------------------
# the generic matrix in exact arithmetic (integers mod a prime)

PRIME = 2147483647  # 2^31 - 1: products of two residues fit in int64


@njit(cache=True)
def _powmod(a, e, prime):
    r = 1
    a %= prime
    while e > 0:
        if e & 1:
            r = r * a % prime
        a = a * a % prime
        e >>= 1
    return r


@njit(cache=True)
def _rref_mod(m, prime):
    """Reduced row echelon form of m (int64 residues) mod prime, in place; returns the pivot
    columns (one per row of the rank)."""
    rows, cols = m.shape
    piv = np.empty(min(rows, cols), dtype=np.int64)
    nz = np.empty(cols, dtype=np.int64)
    r = 0
    for c in range(cols):
        if r == rows:
            break
        k = -1
        for i in range(r, rows):
            if m[i, c] != 0:
                k = i
                break
        if k < 0:
            continue
        if k != r:
            for j in range(c, cols):
                t = m[k, j]
                m[k, j] = m[r, j]
                m[r, j] = t
        inv = _powmod(m[r, c], prime - 2, prime)
        nnz = 0
        for j in range(c, cols):
            if m[r, j] != 0:
                m[r, j] = m[r, j] * inv % prime
                nz[nnz] = j
                nnz += 1
        for i in range(rows):
            if i != r:
                f = m[i, c]
                if f != 0:
                    for q in range(nnz):
                        j = nz[q]
                        m[i, j] = (m[i, j] - f * m[r, j]) % prime
        piv[r] = c
        r += 1
    return piv[:r]


def exact_generic_rigidity(n_bodies: int, bar_a: np.ndarray, bar_b: np.ndarray,
                           rng=None) -> tuple[int, np.ndarray]:
    """Floppy modes and rigid clusters of the generic body-bar rigidity matrix, in exact
    arithmetic: an independent check of :func:`pebble_game` free of rank tolerances.

    A bar's row is (u_x, u_y, m) on its first body and minus that on its second, (u, m) the
    direction and moment about the origin of its line; a generic line has random (u_x, u_y, m).
    Here they are random integers mod the prime p = 2^31 - 1 and the rank and null space come from
    exact Gaussian elimination mod p. A random draw gives the generic rank except with probability
    at most rank / p (Schwartz-Zippel), below 1e-6 here. Two bodies are in one cluster when their
    (v, omega) blocks, motions about the common origin, are equal in every null-space vector.
    Cost: elimination on a dense array, kept banded by a reverse Cuthill-McKee order of the bodies;
    a smoke frame (250 bodies) takes ~20 ms, a 1000-grain frame ~0.5 s.

    Returns (n_floppy = nullity - 3, cluster (n_bodies,) labels numbered by smallest body).
    """
    rng = np.random.default_rng(rng)
    bar_a = np.asarray(bar_a, dtype=np.int64).ravel()
    bar_b = np.asarray(bar_b, dtype=np.int64).ravel()
    nb, ncol = bar_a.size, 3 * n_bodies
    w = rng.integers(1, PRIME, size=(nb, 3), dtype=np.int64)
    # bodies in reverse Cuthill-McKee order and bars by their first body keep the elimination
    # banded (little fill-in); the null space is mapped back to the original bodies below
    adj = coo_matrix((np.ones(nb), (bar_a, bar_b)), shape=(n_bodies, n_bodies)).tocsr()
    order = reverse_cuthill_mckee((adj + adj.T).tocsr(), symmetric_mode=True)
    new = np.empty(n_bodies, dtype=np.int64)
    new[order] = np.arange(n_bodies)
    a, b = new[bar_a], new[bar_b]
    rows = np.argsort(np.minimum(a, b), kind="stable")
    a, b, w = a[rows], b[rows], w[rows]
    m = np.zeros((nb, ncol), dtype=np.int64)
    r = np.arange(nb)
    for q in range(3):
        m[r, 3 * a + q] = w[:, q]
        m[r, 3 * b + q] = (m[r, 3 * b + q] - w[:, q]) % PRIME   # a == b: a zero row
    piv = _rref_mod(m, PRIME) if nb else np.zeros(0, dtype=np.int64)
    rank = piv.size
    free = np.setdiff1d(np.arange(ncol), piv)
    null = np.zeros((ncol, free.size), dtype=np.int64)
    null[free, np.arange(free.size)] = 1
    if rank:
        null[piv] = (-m[:rank][:, free]) % PRIME
    blocks = null.reshape(n_bodies, 3 * free.size)[new]       # back to the original bodies
    _, label = np.unique(blocks, axis=0, return_inverse=True)
    return int(free.size) - 3, canonical_labels(label.ravel())
