"""Per-frame contact observables: active and fully mobilized contacts, bulk selection,
coordination z and mobilization n_m, generalized isostaticity, lost contacts, failing grains,
kinetic energy and displacements.

Conventions (shared by the whole ``analysis`` package)
------------------------------------------------------
* A frame has N grains (mobile and fixed). Contacts are given as ``pair`` (C, 2) int, with
  ``pair[:, 0] = i >= 0`` a grain and ``pair[:, 1] = j`` either a grain (``i < j``) or a wall:
  ``-1`` floor (y = 0), ``-2`` left wall (x = 0), ``-3`` right wall (x = L).
* ``force`` (C, 2) float: ``[f_n, f_t]``; ``status`` (C,) int8: 0 open (touching, zero force),
  1 sticking, 2 sliding (fully mobilized).
* Units: mean diameter d = 1, g = 1, density 1 (mass = pi r^2, moment of inertia m r^2 / 2);
  lengths in d, velocities in sqrt(g d), energies in (density d^2) g d = 1.
* d = 2 throughout (disks).

Counting rule (paper: z = 2 N_c / N, n_m = N_m / N)
---------------------------------------------------
Each grain i has a contact number ``z_i`` (its active contacts, f_n > 0, with *anything*:
grains, fixed grains, walls) and a mobilization number ``m_i`` (its fully mobilized active
contacts). Over a set S of N grains::

    z   = (1/N) sum_{i in S} z_i          (= 2 N_c / N)
    n_m = (1/N) sum_{i in S} m_i / 2      (= N_m / N)

so a contact between two grains of S counts once in N_c (once in N_m if mobilized), and a
contact between a grain of S and anything outside S (a non-bulk grain, a fixed grain, a wall)
counts one half. For the whole packing this is the paper's definition; for a subset it is the
natural per-particle average (a single grain with one mobilized contact has n_m = 1/2, as in the
paper's remark that cluster grains have n_m >= 0.5).

Rattlers: a mobile grain with fewer than ``min_contacts`` (default 2) active contacts is a
rattler; it is removed from S and its contacts are removed from the network before counting
(single pass, not iterated). Fixed grains are never counted.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import checks as _ck

WALL_FLOOR = -1
WALL_LEFT = -2
WALL_RIGHT = -3

SLIDING = 2


# ----------------------------------------------------------------------------------------------
# contact classification


def active_mask(force: np.ndarray) -> np.ndarray:
    """Active contacts: normal force f_n > 0.

    force : (C, 2) float [f_n, f_t].  Returns (C,) bool.
    """
    _ck.shaped("active_mask", "force", force, ("C", 2), finite=True, empty_ok=True)
    return _active_mask(force)


def _active_mask(force):
    """:func:`active_mask` without the checks (inputs the analysis built itself)."""
    force = np.asarray(force, dtype=float).reshape(-1, 2)
    return force[:, 0] > 0.0


def mobilized_mask(force: np.ndarray, status: np.ndarray | None = None, mu=0.5,
                   eps: float | None = None) -> np.ndarray:
    """Fully mobilized (critical) contacts.

    Default (``eps is None``): the solver's sliding flag, ``status == 2``, on active contacts.
    Alternative (``eps`` given): the Coulomb threshold ``|f_t| >= mu f_n (1 - eps)`` on active
    contacts (what one would use for experimental data; ``eps`` absorbs solver tolerance).

    force : (C, 2) [f_n, f_t]; status : (C,) int8 or None (required when eps is None);
    mu : float or (C,) array (e.g. grain and wall friction per contact); eps : float in [0, 1).
    Returns (C,) bool.
    """
    fn = "mobilized_mask"
    _ck.shaped(fn, "force", force, ("C", 2), finite=True, empty_ok=True)
    force = np.asarray(force, dtype=float).reshape(-1, 2)
    c = len(force)
    if status is not None:
        _ck.statuses(fn, "status", status, c, f"force (C={c})")
    if eps is not None:
        _ck.real(fn, "eps", eps, lo=0, hi=1, hi_open=True)
        if np.ndim(mu) == 0:
            _ck.real(fn, "mu", mu, lo=0)
        elif c and (_ck.shaped(fn, "mu", mu, (c,), f"force (C={c})", finite=True).min() < 0):
            _ck.fail(fn, "mu", "be >= 0", str(np.min(mu)))
    return _mobilized_mask(force, status, mu, eps)


def _mobilized_mask(force, status=None, mu=0.5, eps=None):
    """:func:`mobilized_mask` without the checks (inputs the analysis built itself)."""
    force = np.asarray(force, dtype=float).reshape(-1, 2)
    act = force[:, 0] > 0.0
    if eps is None:
        if status is None:
            raise ValueError("mobilized_mask: status is required unless a threshold eps is given")
        return act & (np.asarray(status) == SLIDING)
    if not 0.0 <= eps < 1.0:
        raise ValueError(f"mobilized_mask: eps must be in [0, 1), got {eps}")
    return act & (np.abs(force[:, 1]) >= np.asarray(mu) * force[:, 0] * (1.0 - eps))


def contact_counts(n: int, pair: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Number of selected contacts per grain.

    n : number of grains; pair : (C, 2) int (j < 0 for walls); mask : (C,) bool selecting the
    contacts to count (e.g. active, or mobilized). A grain-grain contact counts for both grains,
    a wall contact for its grain only. Returns (n,) int64.
    """
    fn = "contact_counts"
    _ck.count(fn, "n", n)
    c = _ck.contact_pairs(fn, "pair", pair, n, f"n = {n}")
    _ck.boolean(fn, "mask", mask, c, f"pair (C={c})", empty_ok=True)
    return _contact_counts(n, pair, mask)


def _contact_counts(n, pair, mask):
    """:func:`contact_counts` without the checks (inputs the analysis built itself)."""
    pair = np.asarray(pair).reshape(-1, 2)
    mask = np.asarray(mask, dtype=bool)
    i = pair[mask, 0]
    j = pair[mask, 1]
    counts = np.bincount(i, minlength=n)
    counts += np.bincount(j[j >= 0], minlength=n)
    return counts[:n].astype(np.int64)


def coordination(z_i: np.ndarray, m_i: np.ndarray, select: np.ndarray) -> tuple[float, float, int]:
    """z and n_m over a set of grains (module docstring, counting rule).

    z_i, m_i : (N,) per-grain active and mobilized contact numbers; select : (N,) bool.
    Returns (z, n_m, N_selected); z and n_m are NaN when no grain is selected.
    """
    fn = "coordination"
    n = _ck.shaped(fn, "z_i", z_i, ("N",), finite=True).shape[0]
    _ck.shaped(fn, "m_i", m_i, (n,), f"z_i (N={n})", finite=True)
    _ck.boolean(fn, "select", select, n, f"z_i (N={n})")
    return _coordination(z_i, m_i, select)


def _coordination(z_i, m_i, select):
    """:func:`coordination` without the checks (inputs the analysis built itself)."""
    select = np.asarray(select, dtype=bool)
    n = int(select.sum())
    if n == 0:
        return float("nan"), float("nan"), 0
    return float(z_i[select].sum() / n), float(m_i[select].sum() / (2.0 * n)), n


def dz_gen(z, n_m, d: int = 2):
    """Distance to generalized isostaticity, paper Eq. (1): z - (d + 1) - 2 n_m / d.

    In 2D: delta z_gen = z - 3 - n_m. Works on scalars or arrays (NaN gives NaN).
    """
    _ck.numbers("dz_gen", z=z, n_m=n_m)
    _ck.count("dz_gen", "d", d, lo=1, floats_ok=True)
    return _dz_gen(z, n_m, d)


def _dz_gen(z, n_m, d=2):
    """:func:`dz_gen` without the checks (inputs the analysis built itself)."""
    return np.asarray(z) - (d + 1) - 2.0 * np.asarray(n_m) / d


def dz_local(z, n_m, d: int = 2):
    """Cluster stability margin delta z = z - 2 n_m / d (paper, Fig. 5). In 2D: z - n_m."""
    _ck.numbers("dz_local", z=z, n_m=n_m)
    _ck.count("dz_local", "d", d, lo=1, floats_ok=True)
    return _dz_local(z, n_m, d)


def _dz_local(z, n_m, d=2):
    """:func:`dz_local` without the checks (inputs the analysis built itself)."""
    return np.asarray(z) - 2.0 * np.asarray(n_m) / d


def rattler_mask(z_i: np.ndarray, fixed: np.ndarray, min_contacts: int = 2) -> np.ndarray:
    """Rattlers: mobile grains with fewer than ``min_contacts`` active contacts. (N,) bool."""
    fn = "rattler_mask"
    n = _ck.shaped(fn, "z_i", z_i, ("N",), finite=True).shape[0]
    _ck.boolean(fn, "fixed", fixed, n, f"z_i (N={n})")
    _ck.real(fn, "min_contacts", min_contacts, lo=0)
    return _rattler_mask(z_i, fixed, min_contacts)


def _rattler_mask(z_i, fixed, min_contacts=2):
    """:func:`rattler_mask` without the checks (inputs the analysis built itself)."""
    return (~np.asarray(fixed, dtype=bool)) & (np.asarray(z_i) < min_contacts)


def drop_contacts_of(pair: np.ndarray, mask: np.ndarray, grains: np.ndarray) -> np.ndarray:
    """``mask`` with every contact touching a grain flagged in ``grains`` (N,) bool switched off."""
    pair = np.asarray(pair).reshape(-1, 2)
    i, j = pair[:, 0], pair[:, 1]
    hit = grains[i] | ((j >= 0) & grains[np.maximum(j, 0)])
    return np.asarray(mask, dtype=bool) & ~hit


# ----------------------------------------------------------------------------------------------
# geometry: gaps and layers


def contact_gaps(pair: np.ndarray, position: np.ndarray, radius: np.ndarray,
                 box_length: float) -> np.ndarray:
    """Surface gap of each listed contact (negative = overlap), in d.

    grain-grain: |x_i - x_j| - r_i - r_j; floor: y_i - r_i; left wall: x_i - r_i;
    right wall: L - x_i - r_i. pair (C, 2); position (N, 2); radius (N,). Returns (C,).
    """
    fn = "contact_gaps"
    n = _ck.radii(fn, radius).shape[0]
    _ck.shaped(fn, "position", position, (n, 2), f"radius (N={n})", finite=True)
    _ck.contact_pairs(fn, "pair", pair, n, f"radius (N={n})")
    _ck.real(fn, "box_length", box_length, lo=0, lo_open=True)
    return _contact_gaps(pair, position, radius, box_length)


def _contact_gaps(pair, position, radius, box_length):
    """:func:`contact_gaps` without the checks (inputs the analysis built itself)."""
    pair = np.asarray(pair).reshape(-1, 2)
    i, j = pair[:, 0], pair[:, 1]
    xi = position[i]
    ri = radius[i]
    jj = np.maximum(j, 0)
    gg = np.linalg.norm(xi - position[jj], axis=1) - ri - radius[jj]
    gap = np.where(j >= 0, gg, np.nan)
    gap = np.where(j == WALL_FLOOR, xi[:, 1] - ri, gap)
    gap = np.where(j == WALL_LEFT, xi[:, 0] - ri, gap)
    gap = np.where(j == WALL_RIGHT, box_length - xi[:, 0] - ri, gap)
    return gap


def gap_contacts(position: np.ndarray, radius: np.ndarray, fixed: np.ndarray, box_length: float,
                 reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Every pair of bodies whose surface gap is <= ``reach`` (d), from positions and radii.

    Grain pairs (i < j; scipy.spatial.cKDTree over centres within r_i + r_j + reach, at most
    2 r_max + reach) with at least one mobile grain, and mobile grains with the floor (gap y - r,
    j = -1), the left wall (x - r, j = -2) and the right wall (L - x - r, j = -3). Fixed grains
    have no wall contacts (as in the solver's candidate list). Gaps are negative for overlaps.

    position (N, 2), radius (N,), fixed (N,) bool, box_length L, reach >= 0.
    Returns pair (C, 2) int64 sorted by (i, j), gap (C,) float.
    """
    from scipy.spatial import cKDTree

    pos = np.asarray(position, dtype=float).reshape(-1, 2)
    r = np.asarray(radius, dtype=float).ravel()
    fixed = np.asarray(fixed, dtype=bool).ravel()
    if not reach >= 0.0:
        raise ValueError(f"gap_contacts: reach must be >= 0 (d), got {reach}")
    n = r.size
    if n == 0:
        return np.empty((0, 2), dtype=np.int64), np.empty(0)
    pp = cKDTree(pos).query_pairs(2.0 * r.max() + reach, output_type="ndarray").astype(np.int64)
    pp = np.sort(pp.reshape(-1, 2), axis=1)
    gg = np.linalg.norm(pos[pp[:, 0]] - pos[pp[:, 1]], axis=1) - r[pp[:, 0]] - r[pp[:, 1]]
    keep = (gg <= reach) & ~(fixed[pp[:, 0]] & fixed[pp[:, 1]])
    pairs, gaps = [pp[keep]], [gg[keep]]
    mob = np.flatnonzero(~fixed)
    for wall, wgap in ((WALL_FLOOR, pos[mob, 1] - r[mob]),
                       (WALL_LEFT, pos[mob, 0] - r[mob]),
                       (WALL_RIGHT, box_length - pos[mob, 0] - r[mob])):
        w = wgap <= reach
        pairs.append(np.column_stack([mob[w], np.full(int(w.sum()), wall)]).astype(np.int64))
        gaps.append(wgap[w])
    pair = np.concatenate(pairs).reshape(-1, 2)
    gap = np.concatenate(gaps)
    order = np.lexsort((pair[:, 1], pair[:, 0]))
    return pair[order], gap[order]


@njit(cache=True)
def _surface_hits(x, y, r, x0, spacing, n_rays):
    """For vertical rays at x0 + k*spacing, the index of the grain hit first from above."""
    best_h = np.full(n_rays, -np.inf)
    best_i = np.full(n_rays, -1, dtype=np.int64)
    for i in range(x.shape[0]):
        k_lo = int(np.ceil((x[i] - r[i] - x0) / spacing))
        k_hi = int(np.floor((x[i] + r[i] - x0) / spacing))
        if k_lo < 0:
            k_lo = 0
        if k_hi > n_rays - 1:
            k_hi = n_rays - 1
        for k in range(k_lo, k_hi + 1):
            dx = x0 + k * spacing - x[i]
            h2 = r[i] * r[i] - dx * dx
            if h2 < 0.0:
                continue
            h = y[i] + np.sqrt(h2)
            if h > best_h[k]:
                best_h[k] = h
                best_i[k] = i
    return best_i


def _layer_inputs(fn: str, position, radius, fixed, box_length) -> int:
    """Check a frame's grains: radius (N,) > 0, position (N, 2) finite, fixed (N,) bool, and the
    box length L > 0 (:mod:`tiltpile.analysis.checks`). Returns N."""
    n = _ck.radii(fn, radius).shape[0]
    _ck.shaped(fn, "position", position, (n, 2), f"radius (N={n})", finite=True)
    _ck.boolean(fn, "fixed", fixed, n, f"radius (N={n})")
    _ck.real(fn, "box_length", box_length, lo=0, lo_open=True)
    return n


def top_layer(position: np.ndarray, radius: np.ndarray, fixed: np.ndarray, box_length: float,
              ray_spacing: float = 0.1) -> np.ndarray:
    """Top single layer: mobile grains exposed to the free surface.

    Rule: cast vertical rays downward (box frame, -y) at x = (k + 1/2) * ray_spacing across the
    box [0, L]; a grain is in the top layer if it is the first grain hit by at least one ray,
    i.e. it has a point of its upper boundary that nothing lies above. With ray_spacing = 0.1 d
    every grain with an exposed arc wider than ~0.1 d is found (small grains sitting in the dips
    between two large surface grains included). During avalanches, airborne grains shadow the
    grains below them; that is accepted (the bulk is only interpreted in quiet periods).

    position (N, 2) in d (box frame), radius (N,), fixed (N,) bool. Returns (N,) bool.
    """
    _layer_inputs("top_layer", position, radius, fixed, box_length)
    _ck.real("top_layer", "ray_spacing", ray_spacing, lo=0, lo_open=True)
    return _top_layer(position, radius, fixed, box_length, ray_spacing)


def _top_layer(position, radius, fixed, box_length, ray_spacing=0.1):
    """:func:`top_layer` without the checks (inputs the analysis built itself)."""
    n_rays = max(1, int(np.ceil(box_length / ray_spacing)))
    x0 = 0.5 * ray_spacing
    pos = np.ascontiguousarray(position, dtype=np.float64)
    hits = _surface_hits(pos[:, 0].copy(), pos[:, 1].copy(),
                         np.ascontiguousarray(radius, dtype=np.float64), x0, float(ray_spacing), n_rays)
    top = np.zeros(len(radius), dtype=bool)
    top[hits[hits >= 0]] = True
    return top & ~np.asarray(fixed, dtype=bool)


def bottom_layer(pair: np.ndarray, gaps: np.ndarray, fixed: np.ndarray,
                 touch_tol: float = 0.05) -> np.ndarray:
    """Bottom single layer: mobile grains touching the rough bottom.

    Rule: a mobile grain is in the bottom layer if it has a listed contact (any status) with a
    fixed grain or with the floor whose surface gap is <= ``touch_tol`` (d). The gap test keeps
    candidate contacts of the solver's alert distance out.

    pair (C, 2); gaps (C,) from :func:`contact_gaps`; fixed (N,) bool. Returns (N,) bool.
    """
    fn = "bottom_layer"
    n = _ck.boolean(fn, "fixed", fixed, None).shape[0]
    c = _ck.contact_pairs(fn, "pair", pair, n, f"fixed (N={n})")
    _ck.shaped(fn, "gaps", gaps, (c,), f"pair (C={c})", empty_ok=True)
    _ck.real(fn, "touch_tol", touch_tol)
    return _bottom_layer(pair, gaps, fixed, touch_tol)


def _bottom_layer(pair, gaps, fixed, touch_tol=0.05):
    """:func:`bottom_layer` without the checks (inputs the analysis built itself)."""
    pair = np.asarray(pair).reshape(-1, 2)
    fixed = np.asarray(fixed, dtype=bool)
    i, j = pair[:, 0], pair[:, 1]
    touching = np.asarray(gaps) <= touch_tol
    to_bottom = touching & ((j == WALL_FLOOR) | ((j >= 0) & fixed[np.maximum(j, 0)]))
    # with i < j for grain pairs, a fixed grain may also be pair[:, 0]
    bottom = np.zeros(len(fixed), dtype=bool)
    bottom[i[to_bottom]] = True
    other = touching & (j >= 0) & fixed[i]
    bottom[j[other]] = True
    return bottom & ~fixed


def bulk_mask(position: np.ndarray, radius: np.ndarray, fixed: np.ndarray, pair: np.ndarray,
              box_length: float, ray_spacing: float = 0.1, touch_tol: float = 0.05,
              top: np.ndarray | None = None) -> np.ndarray:
    """Bulk grains: mobile grains that are neither in the top nor in the bottom single layer.

    See :func:`top_layer` and :func:`bottom_layer` for how the layers are found; ``top``: the
    top layer when the caller has it already (None: found here). Returns (N,) bool.
    """
    fn = "bulk_mask"
    n = _layer_inputs(fn, position, radius, fixed, box_length)
    _ck.contact_pairs(fn, "pair", pair, n, f"radius (N={n})")
    _ck.real(fn, "ray_spacing", ray_spacing, lo=0, lo_open=True)
    _ck.real(fn, "touch_tol", touch_tol)
    if top is not None:
        _ck.boolean(fn, "top", top, n, f"radius (N={n})")
    return _bulk_mask(position, radius, fixed, pair, box_length, ray_spacing, touch_tol, top)


def _bulk_mask(position, radius, fixed, pair, box_length, ray_spacing=0.1, touch_tol=0.05,
               top=None):
    """:func:`bulk_mask` without the checks (inputs the analysis built itself)."""
    gaps = _contact_gaps(pair, position, radius, box_length)
    bot = _bottom_layer(pair, gaps, fixed, touch_tol)
    if top is None:
        top = _top_layer(position, radius, fixed, box_length, ray_spacing)
    return ~np.asarray(fixed, dtype=bool) & ~bot & ~top


def bulk_coordination(pair: np.ndarray, active: np.ndarray, mobilized: np.ndarray,
                      bulk: np.ndarray, fixed: np.ndarray, min_contacts: int = 2) -> dict:
    """z, n_m and delta z_gen of a set of grains, with rattlers removed (module docstring).

    pair (C, 2); active, mobilized (C,) bool; bulk (N,) bool selection (usually
    :func:`bulk_mask`); fixed (N,) bool; min_contacts: rattler threshold (0 disables).
    Returns dict with z, n_m, dz_gen (paper Eq. 1, 2D: z - 3 - n_m), n (grains counted),
    n_rattlers (selected grains removed as rattlers), and the per-grain arrays z_i, m_i (after
    rattler removal) and rattler (N,) bool.
    """
    fn = "bulk_coordination"
    n = _ck.boolean(fn, "fixed", fixed, None).shape[0]
    c = _ck.contact_pairs(fn, "pair", pair, n, f"fixed (N={n})")
    _ck.boolean(fn, "active", active, c, f"pair (C={c})", empty_ok=True)
    _ck.boolean(fn, "mobilized", mobilized, c, f"pair (C={c})", empty_ok=True)
    _ck.boolean(fn, "bulk", bulk, n, f"fixed (N={n})")
    _ck.real(fn, "min_contacts", min_contacts, lo=0)
    return _bulk_coordination(pair, active, mobilized, bulk, fixed, min_contacts)


def _bulk_coordination(pair, active, mobilized, bulk, fixed, min_contacts=2) -> dict:
    """:func:`bulk_coordination` without the checks (inputs the analysis built itself)."""
    n = len(fixed)
    z0 = _contact_counts(n, pair, active)
    ratt = _rattler_mask(z0, fixed, min_contacts)
    act = drop_contacts_of(pair, active, ratt)
    mob = act & np.asarray(mobilized, dtype=bool)
    z_i = _contact_counts(n, pair, act)
    m_i = _contact_counts(n, pair, mob)
    sel = np.asarray(bulk, dtype=bool) & ~ratt
    z, n_m, ncount = _coordination(z_i, m_i, sel)
    return {"z": z, "n_m": n_m, "dz_gen": float(_dz_gen(z, n_m)), "n": ncount,
            "n_rattlers": int((np.asarray(bulk, dtype=bool) & ratt).sum()),
            "z_i": z_i, "m_i": m_i, "rattler": ratt}


# ----------------------------------------------------------------------------------------------
# lost contacts and failing grains


def pair_keys(pair: np.ndarray, n: int) -> np.ndarray:
    """Unique int64 key of each contact pair (i, j), j in [-3, n): i * (n + 3) + (j + 3)."""
    _ck.count("pair_keys", "n", n)
    _ck.contact_pairs("pair_keys", "pair", pair, n, f"n = {n}")
    return _pair_keys(pair, n)


def _pair_keys(pair, n):
    """:func:`pair_keys` without the checks (inputs the analysis built itself)."""
    pair = np.asarray(pair, dtype=np.int64).reshape(-1, 2)
    return pair[:, 0] * (n + 3) + (pair[:, 1] + 3)


def lost_contacts(pair_a: np.ndarray, active_a: np.ndarray, pair_b: np.ndarray,
                  active_b: np.ndarray, n: int) -> np.ndarray:
    """Contacts lost between two frames a -> b: active at a and not active at b.

    Contacts are matched by particle pair (i, j), so the order of the contact lists may differ
    between frames; a pair absent from frame b's list or present there with f_n = 0 is lost.

    pair_a (Ca, 2), active_a (Ca,) bool, pair_b (Cb, 2), active_b (Cb,) bool, n grains.
    Returns (Ca,) bool: lost[c] for each contact c of frame a (False for inactive ones).
    """
    fn = "lost_contacts"
    _ck.count(fn, "n", n)
    ca = _ck.contact_pairs(fn, "pair_a", pair_a, n, f"n = {n}")
    cb = _ck.contact_pairs(fn, "pair_b", pair_b, n, f"n = {n}")
    _ck.boolean(fn, "active_a", active_a, ca, f"pair_a (C={ca})", empty_ok=True)
    _ck.boolean(fn, "active_b", active_b, cb, f"pair_b (C={cb})", empty_ok=True)
    return _lost_contacts(pair_a, active_a, pair_b, active_b, n)


def _lost_contacts(pair_a, active_a, pair_b, active_b, n):
    """:func:`lost_contacts` without the checks (inputs the analysis built itself)."""
    ka = _pair_keys(pair_a, n)
    kb = _pair_keys(pair_b, n)[np.asarray(active_b, dtype=bool)]
    return np.asarray(active_a, dtype=bool) & ~np.isin(ka, kb)


def failing_grains(n: int, pair: np.ndarray, lost: np.ndarray,
                   fixed: np.ndarray | None = None) -> np.ndarray:
    """Failing grains: grains that are an end of at least one lost contact. (N,) bool.

    Fixed grains are never failing (when ``fixed`` is given).
    """
    fn = "failing_grains"
    _ck.count(fn, "n", n)
    c = _ck.contact_pairs(fn, "pair", pair, n, f"n = {n}")
    _ck.boolean(fn, "lost", lost, c, f"pair (C={c})", empty_ok=True)
    if fixed is not None:
        _ck.boolean(fn, "fixed", fixed, n, f"n = {n}")
    return _failing_grains(n, pair, lost, fixed)


def _failing_grains(n, pair, lost, fixed=None):
    """:func:`failing_grains` without the checks (inputs the analysis built itself)."""
    f = _contact_counts(n, pair, lost) > 0
    if fixed is not None:
        f &= ~np.asarray(fixed, dtype=bool)
    return f


# ----------------------------------------------------------------------------------------------
# contact rules: which pairs of bodies count as contacts


def parse_contact_rule(rule) -> tuple[str, float | None]:
    """A contact rule, as the analysis parameters ``contact_rule`` and ``lost_rule`` name it.

    * ``"force"``: the contacts carrying a normal force, f_n > 0 (the default);
    * ``"touching"``: every contact the run file lists: those carrying a force and the touching
      ones (gap <= 0) that carry none;
    * ``"gap:<g>"``: every pair of bodies whose surface gap is at most g >= 0 (d), found from the
      positions (:func:`gap_contacts`: grains, fixed grains, walls and the floor), and every
      contact carrying a force: the list a contact-dynamics code keeps at an alert distance g.

    Returns (family, g), g None but for "gap"; ValueError (one line) for anything else.
    """
    if rule in ("force", "touching"):
        return rule, None
    if isinstance(rule, str) and rule.startswith("gap:"):
        try:
            g = float(rule[4:])
        except ValueError:
            g = float("nan")
        if np.isfinite(g) and g >= 0.0:
            return "gap", g
    raise ValueError(f"a contact rule is 'force', 'touching' or 'gap:<g>' with g >= 0 (d), "
                     f"got {rule!r}")


def with_near_pairs(pair: np.ndarray, force: np.ndarray, status: np.ndarray | None,
                    position: np.ndarray, radius: np.ndarray, fixed: np.ndarray,
                    box_length: float, reach: float) -> tuple:
    """The listed contacts and, after them, every other pair of bodies within a surface gap
    ``reach`` (d) (:func:`gap_contacts`, in (i, j) order), the added ones with no force and
    status 0 (open).

    pair (C, 2), force (C, 2), status (C,) or None: the listed contacts (at least one mobile
    grain each); position (N, 2), radius (N,), fixed (N,) bool, box_length L. Returns pair
    (C', 2), force (C', 2), status (C',) or None, listed (C',) bool (True for the C listed
    ones) and gap (C',) the surface gap of every contact (:func:`contact_gaps`).
    """
    pair = np.asarray(pair).reshape(-1, 2)
    force = np.asarray(force, dtype=float).reshape(-1, 2)
    n = len(fixed)
    near, _ = gap_contacts(position, radius, fixed, box_length, reach)
    add = near[~np.isin(_pair_keys(near, n), _pair_keys(pair, n))]
    k = len(add)
    pair = np.concatenate([pair.astype(np.int64), add])
    force = np.concatenate([force, np.zeros((k, 2))])
    if status is not None:
        status = np.asarray(status)
        status = np.concatenate([status, np.zeros(k, dtype=status.dtype)])
    listed = np.concatenate([np.ones(len(pair) - k, dtype=bool), np.zeros(k, dtype=bool)])
    return pair, force, status, listed, _contact_gaps(pair, position, radius, box_length)


def rule_mask(family: str, g: float | None, force: np.ndarray, listed: np.ndarray,
              gap: np.ndarray | None) -> np.ndarray:
    """The contacts a rule (:func:`parse_contact_rule`) counts, among contacts of
    :func:`with_near_pairs` (or the listed ones alone for "force" and "touching"): "force"
    f_n > 0, "touching" the listed ones, "gap" f_n > 0 or gap <= g. Returns (C,) bool."""
    if family == "force":
        return _active_mask(force)
    if family == "touching":
        return np.asarray(listed, dtype=bool).copy()
    return _active_mask(force) | (np.asarray(gap) <= g)


# ----------------------------------------------------------------------------------------------
# kinematics


def kinetic_energy(radius: np.ndarray, velocity: np.ndarray,
                   omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-grain translational and rotational kinetic energy of disks of density 1.

    m = pi r^2, I = m r^2 / 2;  e_t = m |v|^2 / 2,  e_r = I omega^2 / 2.
    radius (N,) d; velocity (N, 2) sqrt(g d); omega (N,) sqrt(g/d) (NaN where unknown: NaN
    energies). Returns two (N,) arrays.
    """
    fn = "kinetic_energy"
    n = _ck.radii(fn, radius).shape[0]
    _ck.shaped(fn, "velocity", velocity, (n, 2), f"radius (N={n})")
    _ck.shaped(fn, "omega", omega, (n,), f"radius (N={n})")
    return _kinetic_energy(radius, velocity, omega)


def _kinetic_energy(radius, velocity, omega):
    """:func:`kinetic_energy` without the checks (inputs the analysis built itself)."""
    r = np.asarray(radius, dtype=float)
    m = np.pi * r * r
    v = np.asarray(velocity, dtype=float).reshape(-1, 2)
    e_t = 0.5 * m * (v[:, 0] ** 2 + v[:, 1] ** 2)
    e_r = 0.25 * m * r * r * np.asarray(omega, dtype=float) ** 2
    return e_t, e_r


def displacement(position: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """|x_i - x_i^ref| per grain, in d. position, reference (N, 2) (or (..., N, 2), reference
    broadcasting against position). Returns (N,) (or (..., N))."""
    for name, x in (("position", position), ("reference", reference)):
        a = _ck.asarray("displacement", name, x)
        if a.ndim < 1 or a.shape[-1] != 2:
            _ck.fail("displacement", name, "have shape (N, 2)", str(a.shape))
    _ck.broadcast("displacement", position=position, reference=reference)
    dx = np.asarray(position, dtype=float) - np.asarray(reference, dtype=float)
    return np.sqrt((dx * dx).sum(axis=-1))


def gravity_vector(theta_deg) -> np.ndarray:
    """Unit gravity in the box frame, g = (sin theta, -cos theta); (2,) or (..., 2)."""
    _ck.asarray("gravity_vector", "theta_deg", theta_deg)
    t = np.deg2rad(np.asarray(theta_deg, dtype=float))
    return np.stack([np.sin(t), -np.cos(t)], axis=-1)
