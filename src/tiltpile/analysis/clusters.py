"""Critical clusters: connected groups of grains carrying fully mobilized contacts.

Definition (the paper's, from its text and Fig. 3, and ours: docs/method.md, "Critical clusters")
-----------------------------------------------------------------------------------------------
* A grain is *critical* if it has at least one fully mobilized active contact (with a grain, a
  fixed grain or a wall). Only grains allowed by ``include`` (default: all mobile grains) can be
  critical; fixed grains never are.
* ``link="contacts"`` (default): two critical grains are linked when they share an active
  contact (f_n > 0), mobilized or not. ``link="mobilized"``: only a shared fully mobilized
  contact links them.
* A cluster is a connected component of critical grains under these links
  (``scipy.sparse.csgraph.connected_components``). An isolated critical grain is a cluster of size 1.

Per cluster: size s (grains), z and n_m with the per-grain counting rule of
:mod:`tiltpile.analysis.contacts` (z = mean z_i over the cluster, n_m = mean m_i / 2, every active
contact of a cluster grain counted, whatever its partner), delta z = z - 2 n_m / d (paper Fig. 5,
2D: z - n_m) and the orientation of its long axis relative to gravity.

Orientation: the gyration tensor G = <(x - <x>)(x - <x>)^T> of the grain centres (unweighted) has
its largest eigenvalue along the long axis, at angle phi = atan2(2 G_xy, G_xx - G_yy) / 2 from the
box x axis. With gravity g = (sin theta, -cos theta), the angle between the (unoriented) long axis
and gravity is alpha = arccos(|sin(theta - phi)|), in degrees in [0, 90] (0 = along gravity,
90 = perpendicular). Undefined (NaN) for size-1 clusters and isotropic gyration tensors.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from . import checks as _ck
from .contacts import _contact_counts, _dz_local


def critical_grains(n: int, pair: np.ndarray, mobilized: np.ndarray,
                    include: np.ndarray | None = None) -> np.ndarray:
    """Grains with at least one fully mobilized contact, restricted to ``include``. (N,) bool.

    n grains; pair (C, 2) int (j < 0 walls); mobilized (C,) bool; include (N,) bool or None."""
    fn = "critical_grains"
    _ck.count(fn, "n", n)
    c = _ck.contact_pairs(fn, "pair", pair, n, f"n = {n}")
    _ck.boolean(fn, "mobilized", mobilized, c, f"pair (C={c})", empty_ok=True)
    if include is not None:
        _ck.boolean(fn, "include", include, n, f"n = {n}")
    return _critical_grains(n, pair, mobilized, include)


def _critical_grains(n, pair, mobilized, include=None):
    """:func:`critical_grains` without the checks (inputs the analysis built itself)."""
    crit = _contact_counts(n, pair, mobilized) > 0
    if include is not None:
        crit &= np.asarray(include, dtype=bool)
    return crit


def critical_clusters(n: int, pair: np.ndarray, active: np.ndarray, mobilized: np.ndarray,
                      include: np.ndarray | None = None, link: str = "contacts") -> np.ndarray:
    """Label the critical clusters (module docstring).

    n grains; pair (C, 2) int (j < 0 walls); active, mobilized (C,) bool; include (N,) bool grains
    that may belong to clusters (pass ``~fixed``, or a bulk mask); link "contacts" | "mobilized".

    Returns labels (N,) int64: -1 for grains in no cluster, else the cluster index 0..K-1, with
    clusters numbered by decreasing size (ties: by smallest grain index).
    """
    fn = "critical_clusters"
    if link not in ("contacts", "mobilized"):
        raise ValueError(f"critical_clusters: link must be 'contacts' or 'mobilized', got {link!r}")
    _ck.count(fn, "n", n)
    c = _ck.contact_pairs(fn, "pair", pair, n, f"n = {n}")
    _ck.boolean(fn, "active", active, c, f"pair (C={c})", empty_ok=True)
    _ck.boolean(fn, "mobilized", mobilized, c, f"pair (C={c})", empty_ok=True)
    if include is not None:
        _ck.boolean(fn, "include", include, n, f"n = {n}")
    return _critical_clusters(n, pair, active, mobilized, include, link)


def _critical_clusters(n, pair, active, mobilized, include=None, link="contacts"):
    """:func:`critical_clusters` without the checks (inputs the analysis built itself)."""
    pair = np.asarray(pair).reshape(-1, 2)
    active = np.asarray(active, dtype=bool)
    mobilized = np.asarray(mobilized, dtype=bool) & active
    crit = _critical_grains(n, pair, mobilized, include)
    labels = np.full(n, -1, dtype=np.int64)
    members = np.flatnonzero(crit)
    if members.size == 0:
        return labels
    i, j = pair[:, 0], pair[:, 1]
    edge = (mobilized if link == "mobilized" else active) & (j >= 0)
    jj = np.maximum(j, 0)
    edge &= crit[i] & crit[jj]
    local = np.full(n, -1, dtype=np.int64)
    local[members] = np.arange(members.size)
    a, b = local[i[edge]], local[jj[edge]]
    m = members.size
    graph = coo_matrix((np.ones(a.size, dtype=np.int8), (a, b)), shape=(m, m))
    _, comp = connected_components(graph, directed=False)
    sizes = np.bincount(comp)
    first = np.full(sizes.size, np.iinfo(np.int64).max)
    np.minimum.at(first, comp, members)
    order = np.lexsort((first, -sizes))      # by size desc, then smallest grain index
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    labels[members] = rank[comp]
    return labels


def _labels(fn: str, labels) -> int:
    """Check cluster labels: (N,) integers >= -1 (:mod:`tiltpile.analysis.checks`). Returns N."""
    a = _ck.shaped(fn, "labels", labels, ("N",), kinds="iu", empty_ok=True)
    if a.size and a.min() < -1:
        _ck.fail(fn, "labels", "be cluster labels 0, 1, ... or -1 (no cluster)", str(a.min()))
    return a.size


def cluster_sizes(labels: np.ndarray) -> np.ndarray:
    """Sizes (K,) of the clusters labelled 0..K-1 in ``labels`` (N,) (-1 = none)."""
    _labels("cluster_sizes", labels)
    labels = np.asarray(labels)
    return np.bincount(labels[labels >= 0]) if np.any(labels >= 0) else np.zeros(0, dtype=np.int64)


def gyration_axes(labels: np.ndarray, position: np.ndarray) -> dict:
    """Gyration tensor per cluster, vectorized over clusters.

    labels (N,) from :func:`critical_clusters`; position (N, 2). Returns dict of (K,) arrays:
    size, x_com, y_com, gxx, gyy, gxy, phi_deg (long-axis angle from the box x axis, in
    (-90, 90]), rg_long, rg_short (square roots of the eigenvalues, in d).
    """
    n = _labels("gyration_axes", labels)
    _ck.shaped("gyration_axes", "position", position, (n, 2), f"labels (N={n})", finite=True)
    return _gyration_axes(labels, position)


def _gyration_axes(labels, position) -> dict:
    """:func:`gyration_axes` without the checks (inputs the analysis built itself)."""
    labels = np.asarray(labels)
    sel = labels >= 0
    k = int(labels[sel].max()) + 1 if sel.any() else 0
    lab = labels[sel]
    x = np.asarray(position, dtype=float)[sel]
    size = np.bincount(lab, minlength=k).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = np.bincount(lab, x[:, 0], minlength=k) / size
        cy = np.bincount(lab, x[:, 1], minlength=k) / size
        dx = x[:, 0] - cx[lab]
        dy = x[:, 1] - cy[lab]
        gxx = np.bincount(lab, dx * dx, minlength=k) / size
        gyy = np.bincount(lab, dy * dy, minlength=k) / size
        gxy = np.bincount(lab, dx * dy, minlength=k) / size
    phi = 0.5 * np.arctan2(2.0 * gxy, gxx - gyy)
    half_tr = 0.5 * (gxx + gyy)
    root = np.sqrt(0.25 * (gxx - gyy) ** 2 + gxy ** 2)
    lam1 = half_tr + root
    lam2 = np.maximum(half_tr - root, 0.0)
    return {"size": size.astype(np.int64), "x_com": cx, "y_com": cy, "gxx": gxx, "gyy": gyy,
            "gxy": gxy, "phi_deg": np.rad2deg(phi), "rg_long": np.sqrt(lam1),
            "rg_short": np.sqrt(lam2), "anisotropy": root}


def orientation_to_gravity(phi_deg, theta_deg) -> np.ndarray:
    """Angle (deg, in [0, 90]) between an unoriented axis at phi (from box x) and gravity.

    Gravity in the box frame is (sin theta, -cos theta), so alpha = arccos(|sin(theta - phi)|).
    phi_deg, theta_deg: numbers or arrays that broadcast (NaN gives NaN).
    """
    _ck.numbers("orientation_to_gravity", phi_deg=phi_deg, theta_deg=theta_deg)
    return _orientation_to_gravity(phi_deg, theta_deg)


def _orientation_to_gravity(phi_deg, theta_deg):
    """:func:`orientation_to_gravity` without the checks (inputs the analysis built itself)."""
    d = np.deg2rad(np.asarray(theta_deg, dtype=float) - np.asarray(phi_deg, dtype=float))
    return np.rad2deg(np.arccos(np.clip(np.abs(np.sin(d)), 0.0, 1.0)))


def cluster_table(labels: np.ndarray, position: np.ndarray, z_i: np.ndarray, m_i: np.ndarray,
                  theta_deg: float, rel_tol: float = 1e-9) -> pd.DataFrame:
    """Per-cluster properties of one frame.

    labels (N,) cluster labels (-1 none); position (N, 2) d; z_i, m_i (N,) per-grain active and
    mobilized contact numbers (all partners); theta_deg: tilt of gravity.

    Returns a DataFrame with one row per cluster (in label order: decreasing size) and columns
    cluster, size, z, n_m, dz (= z - n_m, 2D), orientation_deg (NaN for size 1 or an isotropic
    gyration tensor, i.e. eigenvalue split < rel_tol * trace), phi_deg, rg_long, rg_short,
    x_com, y_com.
    """
    fn = "cluster_table"
    n = _labels(fn, labels)
    _ck.shaped(fn, "position", position, (n, 2), f"labels (N={n})", finite=True)
    _ck.shaped(fn, "z_i", z_i, (n,), f"labels (N={n})", finite=True)
    _ck.shaped(fn, "m_i", m_i, (n,), f"labels (N={n})", finite=True)
    _ck.real(fn, "theta_deg", theta_deg)
    _ck.real(fn, "rel_tol", rel_tol, lo=0)
    return _cluster_table(labels, position, z_i, m_i, theta_deg, rel_tol)


def _cluster_table(labels, position, z_i, m_i, theta_deg, rel_tol=1e-9) -> pd.DataFrame:
    """:func:`cluster_table` without the checks (inputs the analysis built itself)."""
    labels = np.asarray(labels)
    sel = labels >= 0
    g = _gyration_axes(labels, position)
    k = g["size"].size
    size = g["size"].astype(float)
    lab = labels[sel]
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.bincount(lab, np.asarray(z_i, dtype=float)[sel], minlength=k) / size
        n_m = np.bincount(lab, np.asarray(m_i, dtype=float)[sel], minlength=k) / (2.0 * size)
    orient = _orientation_to_gravity(g["phi_deg"], theta_deg)
    undefined = (g["size"] < 2) | (g["anisotropy"] <= rel_tol * (g["gxx"] + g["gyy"]))
    orient = np.where(undefined, np.nan, orient)
    phi = np.where(undefined, np.nan, g["phi_deg"])
    return pd.DataFrame({
        "cluster": np.arange(k, dtype=np.int64), "size": g["size"], "z": z, "n_m": n_m,
        "dz": _dz_local(z, n_m), "orientation_deg": orient, "phi_deg": phi,
        "rg_long": g["rg_long"], "rg_short": g["rg_short"], "x_com": g["x_com"], "y_com": g["y_com"],
    })
