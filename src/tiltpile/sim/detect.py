"""Candidate contacts: a cell list within an alert distance, and warm-start matching.

A *candidate* is a pair of bodies whose gap is below the alert distance ``alert`` when the list
is built: grain-grain (i < j, never two fixed grains) and grain-wall (mobile grains only). Walls
are indexed N + k (k = 0 floor, 1 left, 2 right; ids -1, -2, -3 in run files).

The list stays valid while no grain has moved more than ``alert / 2`` since the build: two grains
not in the list were at least ``alert`` apart and cannot have closed the gap (Verlet's argument).
The stepper rebuilds before that can happen (``step``), so contacts are not missed, and it counts
the steps in which a grain nevertheless moved farther (a flag of too large a time step).

Contacts are built sorted by key = i * (N + 3) + j; impulses carry over to a rebuilt list by
particle pair (a merge over both lists sorted by key: warm start across rebuilds). The
"interleaved" sweep then stores them in the order of ``interleave``.
"""

from __future__ import annotations

import numpy as np

from tiltpile.sim.jit import njit


@njit
def _grow(a, size):
    b = np.empty(size, dtype=a.dtype)
    b[: a.shape[0]] = a
    return b


@njit
def build_candidates(pos, radius, fixed, box_length, alert):
    """All candidate contacts, sorted by key.

    pos (N, 2), radius (N,), fixed (N,) bool, box_length L, alert distance [d].
    Returns ci (C,) int32 grain index, cj (C,) int32 grain index or N + wall, key (C,) int64.
    """
    n = pos.shape[0]
    rmax = 0.0
    ylo = np.inf
    yhi = -np.inf
    for i in range(n):
        rmax = max(rmax, radius[i])
        ylo = min(ylo, pos[i, 1])
        yhi = max(yhi, pos[i, 1])
    cell = 2.0 * rmax + alert
    ncx = max(1, int(box_length / cell))
    ncy = max(1, int((yhi - ylo) / cell) + 1)
    hx = box_length / ncx
    ncell = ncx * ncy
    cell_of = np.empty(n, dtype=np.int64)
    count = np.zeros(ncell + 1, dtype=np.int64)
    for i in range(n):
        cx = min(max(int(pos[i, 0] / hx), 0), ncx - 1)
        cy = min(max(int((pos[i, 1] - ylo) / cell), 0), ncy - 1)
        c = cy * ncx + cx
        cell_of[i] = c
        count[c + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        order[fill[cell_of[i]]] = i
        fill[cell_of[i]] += 1

    cap = 4 * n + 16
    ci = np.empty(cap, dtype=np.int32)
    cj = np.empty(cap, dtype=np.int32)
    m = 0
    for i in range(n):
        c = cell_of[i]
        cx = c % ncx
        cy = c // ncx
        xi = pos[i, 0]
        yi = pos[i, 1]
        ri = radius[i]
        for ny in range(max(cy - 1, 0), min(cy + 2, ncy)):
            for nx in range(max(cx - 1, 0), min(cx + 2, ncx)):
                cc = ny * ncx + nx
                for q in range(start[cc], start[cc + 1]):
                    j = order[q]
                    if j <= i or (fixed[i] and fixed[j]):
                        continue
                    dx = xi - pos[j, 0]
                    dy = yi - pos[j, 1]
                    reach = ri + radius[j] + alert
                    if dx * dx + dy * dy < reach * reach:
                        if m == ci.shape[0]:
                            ci = _grow(ci, 2 * m)
                            cj = _grow(cj, 2 * m)
                        ci[m] = i
                        cj[m] = j
                        m += 1
        if fixed[i]:
            continue
        for w in range(3):
            if w == 0:
                gap = yi - ri
            elif w == 1:
                gap = xi - ri
            else:
                gap = box_length - xi - ri
            if gap < alert:
                if m == ci.shape[0]:
                    ci = _grow(ci, 2 * m)
                    cj = _grow(cj, 2 * m)
                ci[m] = i
                cj[m] = n + w
                m += 1
    key = np.empty(m, dtype=np.int64)
    for k in range(m):
        key[k] = np.int64(ci[k]) * (n + 3) + cj[k]
    srt = np.argsort(key, kind="mergesort")
    return ci[:m][srt].copy(), cj[:m][srt].copy(), key[srt].copy()


@njit
def carry_impulses(old_key, old_p, new_key, new_p):
    """Copy impulses of pairs present in both key lists; others start at zero.

    The lists may be in any order (an interleaved list is not sorted by key). old_p (C_old, 2),
    new_p (C_new, 2) [normal, tangential]. Returns how many were carried.
    """
    oo = np.argsort(old_key, kind="mergesort")
    no = np.argsort(new_key, kind="mergesort")
    a = 0
    carried = 0
    for q in range(new_key.shape[0]):
        b = no[q]
        while a < old_key.shape[0] and old_key[oo[a]] < new_key[b]:
            a += 1
        if a < old_key.shape[0] and old_key[oo[a]] == new_key[b]:
            new_p[b, 0] = old_p[oo[a], 0]
            new_p[b, 1] = old_p[oo[a], 1]
            carried += 1
        else:
            new_p[b, 0] = 0.0
            new_p[b, 1] = 0.0
    return carried


INTERLEAVE_WINDOW = 8


@njit
def interleave(ci, cj, n_bodies, window=INTERLEAVE_WINDOW):
    """An order of the contacts in which no body occurs twice within ``window`` consecutive
    places, staying close to the given (key) order.

    Greedy list scheduling over a lookahead of 4 * window contacts: each place takes the first
    waiting contact whose two bodies were last used more than ``window`` places ago, or the
    oldest waiting one if none qualifies. Why: a local solve reads and writes the velocities of
    its two bodies in one chain of dependent arithmetic; in key order consecutive contacts share
    grain i, so each update waits for the previous one. With the chains apart the CPU overlaps
    them (``solver._sweep_stored``; the gain: ``docs/performance.md``).
    ci, cj (C,) body indices; n_bodies N + 3. Returns the permutation (C,) int64.
    """
    nc = ci.shape[0]
    look = 4 * window
    last = np.full(n_bodies, -(1 << 40), np.int64)
    out = np.empty(nc, np.int64)
    buf = np.empty(look, np.int64)
    nbuf = 0
    nxt = 0
    for place in range(nc):
        while nbuf < look and nxt < nc:
            buf[nbuf] = nxt
            nbuf += 1
            nxt += 1
        pick = 0
        for q in range(nbuf):
            a = buf[q]
            if last[ci[a]] < place - window and last[cj[a]] < place - window:
                pick = q
                break
        a = buf[pick]
        for q in range(pick, nbuf - 1):
            buf[q] = buf[q + 1]
        nbuf -= 1
        out[place] = a
        last[ci[a]] = place
        last[cj[a]] = place
    return out


def wall_ids(cj: np.ndarray, n: int) -> np.ndarray:
    """Kernel indices (N + k for walls) -> run-file ids (-1 floor, -2 left, -3 right)."""
    cj = np.asarray(cj)
    return np.where(cj >= n, -(cj - n) - 1, cj).astype(np.int32)


def kernel_ids(j: np.ndarray, n: int) -> np.ndarray:
    """Run-file ids (-1 floor, -2 left, -3 right) -> kernel indices (N + k for walls): the
    inverse of :func:`wall_ids`."""
    j = np.asarray(j)
    return np.where(j < 0, n - 1 - j, j).astype(np.int32)
