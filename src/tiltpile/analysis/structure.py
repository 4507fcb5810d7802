"""The pile's structure at rest: packing fraction and contact fabric.

What a preparation history leaves in a pile besides its coordination: how densely it is packed
and how its contacts are oriented. Deboeuf et al. (PRE 72, 051305, 2005) followed the fabric of
the contact network through their tilting cycles; a cycled pile is expected to keep an
anisotropy that a fresh one does not have.

* :func:`bulk_window` -- a rectangle inside the pile, ``margin`` away from the side walls, the top
  of the rough bottom and the lowest point of the free surface;
* :func:`packing_fraction` -- the fraction of a rectangle covered by disks, counted on a square
  grid of points (resolution ``spacing``; the error of a grid count of a smooth region falls
  like spacing^2, below 1e-3 at the default 0.02 d for our grains: tests/analysis/test_analysis_structure.py);
* :func:`surface_tilt_deg` -- the free surface's tilt against the floor (a line through the tops
  of the top-layer grains);
* :func:`fabric` -- the fabric tensor F = <n n> of the active grain-grain contacts (n the unit
  branch vector; F has trace 1), its anisotropy a = 2 (l1 - l2) / (l1 + l2) = 2 (l1 - l2) and
  the direction of its major axis from the box's normal (the vertical at theta = 0).

Conventions as in :mod:`tiltpile.analysis.contacts` (box frame, d = 1, walls as negative ids).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .contacts import top_layer


def bulk_window(position: np.ndarray, radius: np.ndarray, fixed: np.ndarray, box_length: float,
                margin: float = 3.0) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1): the rectangle ``margin`` (d) inside the side walls, above the top of the
    fixed bottom grains (the floor when there are none) and below the lowest surface grain's
    centre (:func:`tiltpile.analysis.contacts.top_layer`, over the same x range). ValueError when
    the pile is too thin or short for such a rectangle."""
    position = np.asarray(position, dtype=float)
    radius = np.asarray(radius, dtype=float)
    fixed = np.asarray(fixed, dtype=bool)
    x0, x1 = margin, box_length - margin
    y_bottom = float((position[fixed, 1] + radius[fixed]).max()) if fixed.any() else 0.0
    top = top_layer(position, radius, fixed, box_length)
    inside = top & (position[:, 0] >= x0) & (position[:, 0] <= x1)
    if not inside.any():
        raise ValueError("bulk_window: no surface grain between the margins")
    y0, y1 = y_bottom + margin, float(position[inside, 1].min()) - margin
    if x1 <= x0 or y1 <= y0:
        raise ValueError(f"bulk_window: the pile ({box_length:g} d long, surface at "
                         f"{y1 + margin:.3g} d) leaves no window {margin:g} d inside it")
    return x0, x1, y0, y1


def packing_fraction(position: np.ndarray, radius: np.ndarray, window, spacing: float = 0.02
                     ) -> float:
    """Fraction of ``window`` = (x0, x1, y0, y1) covered by the disks (centres ``position`` (N,
    2), radii (N,)), from a square grid of points ``spacing`` apart (cell centres): the share of
    points that lie inside some disk."""
    x0, x1, y0, y1 = (float(v) for v in window)
    if not (x1 > x0 and y1 > y0):
        raise ValueError(f"packing_fraction: empty window {window!r}")
    if spacing <= 0:
        raise ValueError(f"packing_fraction: spacing must be positive, got {spacing!r}")
    position = np.ascontiguousarray(position, dtype=np.float64).reshape(-1, 2)
    radius = np.ascontiguousarray(radius, dtype=np.float64)
    nx, ny = max(1, int(round((x1 - x0) / spacing))), max(1, int(round((y1 - y0) / spacing)))
    grid = _cover(position, radius, x0, y0, (x1 - x0) / nx, (y1 - y0) / ny, nx, ny)
    return float(grid.mean())


@njit(cache=True)
def _cover(position, radius, x0, y0, hx, hy, nx, ny):
    """(nx, ny) bool: cell centres x0 + (i + 1/2) hx, y0 + (j + 1/2) hy inside some disk."""
    grid = np.zeros((nx, ny), dtype=np.bool_)
    for k in range(position.shape[0]):
        cx, cy, r = position[k, 0], position[k, 1], radius[k]
        i_lo = max(0, int(np.ceil((cx - r - x0) / hx - 0.5)))
        i_hi = min(nx - 1, int(np.floor((cx + r - x0) / hx - 0.5)))
        j_lo = max(0, int(np.ceil((cy - r - y0) / hy - 0.5)))
        j_hi = min(ny - 1, int(np.floor((cy + r - y0) / hy - 0.5)))
        for i in range(i_lo, i_hi + 1):
            dx = x0 + (i + 0.5) * hx - cx
            for j in range(j_lo, j_hi + 1):
                dy = y0 + (j + 0.5) * hy - cy
                if dx * dx + dy * dy <= r * r:
                    grid[i, j] = True
    return grid


def fabric(pair: np.ndarray, position: np.ndarray, active: np.ndarray,
           select: np.ndarray | None = None) -> dict:
    """Fabric of the active grain-grain contacts (walls left out).

    pair (C, 2), position (N, 2), active (C,) bool; select (N,) bool: only contacts with at
    least one selected grain (None: all). Returns dict with tensor (2, 2), anisotropy
    a = 2 (l1 - l2) (0: isotropic, 2: all contacts parallel), major_deg (direction of the major
    axis from the box normal y, in (-90, 90], positive towards +x) and n_contacts.
    """
    pair = np.asarray(pair).reshape(-1, 2)
    position = np.asarray(position, dtype=float)
    use = np.asarray(active, dtype=bool) & (pair[:, 1] >= 0)
    if select is not None:
        sel = np.asarray(select, dtype=bool)
        use &= sel[pair[:, 0]] | sel[np.maximum(pair[:, 1], 0)]
    p = pair[use]
    if len(p) == 0:
        return {"tensor": np.full((2, 2), np.nan), "anisotropy": np.nan, "major_deg": np.nan,
                "n_contacts": 0}
    b = position[p[:, 1]] - position[p[:, 0]]
    n = b / np.linalg.norm(b, axis=1)[:, None]
    t = n.T @ n / len(n)
    w, v = np.linalg.eigh(t)
    major = v[:, 1]
    ang = float(np.degrees(np.arctan2(major[0], major[1])))  # from +y towards +x
    ang = ang - 180.0 if ang > 90.0 else (ang + 180.0 if ang <= -90.0 else ang)
    return {"tensor": t, "anisotropy": float(2.0 * (w[1] - w[0]) / (w[0] + w[1])),
            "major_deg": ang, "n_contacts": int(len(n))}


SURFACE_MARGIN = 4.0  # [d] from each side wall: the surface fit leaves the wall regions out


def surface_tilt_deg(position, radius, fixed, box_length: float,
                     margin: float = SURFACE_MARGIN) -> float:
    """The free surface's tilt against the box floor [deg], positive when it rises towards the
    wall at x = L (where the pile flows at positive theta): the least-squares line through the
    tops (y + r) of the top-layer grains (:func:`tiltpile.analysis.contacts.top_layer`) between
    ``margin`` and L - ``margin``. The surface's slope to the horizontal at box angle theta is
    theta minus this (the angle a repose angle is usually quoted as)."""
    pos = np.asarray(position, dtype=float)
    top = top_layer(pos, radius, fixed, box_length)
    sel = top & (pos[:, 0] >= margin) & (pos[:, 0] <= box_length - margin)
    if sel.sum() < 2:
        return math.nan
    slope = np.polyfit(pos[sel, 0], pos[sel, 1] + np.asarray(radius)[sel], 1)[0]
    return float(np.degrees(np.arctan(slope)))
