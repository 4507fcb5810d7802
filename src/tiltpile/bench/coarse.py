"""Could a coarse correction speed NLGS up? What the best one could remove of its error, measured.

Usage: python -m tiltpile.bench.coarse RUN --frames F [F ...] [--steps S] [--caps K ...]
                                       [--long L] [--blocks B ...] [--warm W] [--json OUT]
                                       [--chart PNG] [--quiet] [--oracle K [--ridge R] [--feasible]]
       python -m tiltpile.bench.coarse --plot JSON [JSON ...] --chart PNG
  RUN      a run file (``tiltpile simulate``); FRAMES frame indices (paper preset: frame 160 =
           8 deg, 240 = 12 deg, 340 = 17 deg; ``tiltpile info RUN`` lists the angles)
  --steps  tilt steps measured after each frame (default 20)
  --caps   sweeps at which the iterate's error is measured (default 100 300 1000 3000; the run's
           solver.max_iter is always added)
  --long   sweeps of the reference solve of every step (default 20 000)
  --blocks block sizes in grain diameters (default 20 10 5 3)
  --warm   steps at max_iter 20 000 that rebuild the impulses (default 10)
  --json   write the rows; --chart draw them (PNG); --plot draw earlier --json files instead
  --oracle K  instead of the bounds: NLGS with an oracle coarse correction every K sweeps in each
           impulse subspace, against plain NLGS (below); --ridge R its projection's relative
           ridge (default 1e-3), --feasible project each correction on the Coulomb cones

A coarse correction (a two-level method) restricts each correction to a small subspace: every k
sweeps it moves the iterate by the element of the subspace that some coarse problem picks, and
Gauss-Seidel goes on from there. Whatever that coarse problem is, one correction can remove at
most the part of the current error that lies in the subspace: in the kinetic-energy norm, the
best element leaves the error minus its energy-orthogonal projection. This module measures that
bound in the steps of a run, for the subspaces the issue names, instead of building one.

From each frame's rebuilt state (``flow_caps.rebuilt_state``), S tilt steps as the run makes them
(``settle.prepare_step``; the pile goes on from the run's own solve, one ``nlgs`` call at its
cap). Within every step the same iteration runs on to ``--long`` sweeps in chunks (the production
``nlgs`` called again from where it stopped; ``bench.settle`` shows that this is the one-call
iteration), and the body velocities are kept at each cap. The error at cap k is
e = v(k) - v_ref, v_ref the velocities at ``--long`` sweeps, over the mobile grains, in the
kinetic-energy norm ||e||^2 = sum_i m_i (e_x^2 + e_y^2) + m_i e_s^2 / 2 (disks, I = m r^2 / 2,
s = r omega the rim speed the kernels carry). A step whose solve meets solver.tol before cap k has
no error there and is left out of that cap's medians.

The subspaces, on a square grid of blocks B x B [d] laid over the box:
- ``rigid``: every grain moves with its block as one rigid body (issue 26's item 4): dv_i = U + Omega z x (x_i - X), ds_i = r_i Omega,
  3 unknowns per block, grains binned by their centres;
- ``stress``: the impulses change as a uniform stress sigma (symmetric, 3 unknowns) per block
  would have them change, dp_n = n.sigma.n, dp_t = t.sigma.n, contacts binned by their contact
  point, and the velocities with them (dv = M^-1 H dp, exactly as the sweeps push impulses);
- ``stress_grad``: the same with sigma linear across the block (9 unknowns per block).

Measured per step and cap: the relative error ||e|| / ||v_ref||; for each subspace and block size
the captured fraction f = ||P e||^2 / ||e||^2 (P the energy-orthogonal projection), so that one
ideal correction would cut the error's norm by at most 1 - sqrt(1 - f); the same fraction of the
motion itself (v_ref) and of the step's change (v_ref - the warm start) for ``rigid``; and the
spatial correlation of the error's translational part, C(r) = <e_i . e_j> / <|e|^2> over the
pairs of mobile grains in [r, r + 1) d, beside that of v_ref. ``docs/performance-log.md`` records
what it measured.

``--oracle K`` runs the corrections instead of bounding them, in ``stress``, ``stress_grad``,
``interface`` (any change of the impulses of the contacts between two blocks, which is what a
rigid-block coarse problem solves for when the impulses inside the blocks are kept) and
``rigid`` (the block-rigid move, realised by the least-norm impulses over all the contacts that
produce it: a block moves rigidly only if the contacts inside it carry the impulses for it).
Every K sweeps the iterate takes the best element of the subspace, computed from the long solve
(an oracle coarse problem), on its impulses and, through G, on its velocities, so that it stays
a consistent pair, and Gauss-Seidel goes on from there (``oracle_step``). Reported: the error
against the sweeps, and the sweep at which each variant reaches the error plain NLGS has at the
run's cap. A real coarse correction in the subspace picks a worse move than the oracle's, and
pays for its coarse solve; the sweeps after a correction depend on the impulses too, which the
oracle picks by least norm, so this is the ceiling of each correction rather than a proof for
the whole iteration.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

from tiltpile.bench.settle import (check_outputs, check_run, finish_step, frame_systems,
                                   prepare_step, read_results)
from tiltpile.sim.solver import C_MU, C_NX, C_NY, IMPULSE, V_IM, nlgs

SPACES = ("rigid", "stress", "stress_grad")
CORR_AT = (1, 2, 4, 8)       # left edges [d] of the correlation bins [r, r + 1)
DEFAULT_CAPS = (100, 300, 1000, 3000)
DEFAULT_BLOCKS = (20, 10, 5, 3)
RIDGE = 1e-10                # relative ridge of the projections' normal equations (the bounds)
ORACLE_RIDGE = 1e-3          # the oracle's (``--ridge``): smaller ones let ill-conditioned interface
                             # columns make huge self-stresses that the sweeps' projections turn into motion


# -- the energy norm and the subspaces -------------------------------------------------------------

def energy_weights(vel, n: int) -> np.ndarray:
    """(N + 3, 3) weights of the kinetic-energy norm per velocity component: m, m, m / 2 for the
    mobile grains (vx, vy, s), 0 for fixed grains and walls."""
    im = vel[:, V_IM]
    m = np.zeros(vel.shape[0])
    mob = im > 0.0
    mob[n:] = False
    m[mob] = 1.0 / im[mob]
    return np.stack([m, m, 0.5 * m], axis=1)


def norm2(e, w) -> float:
    """||e||^2 in the energy norm: e and w (bodies, 3)."""
    return float(np.sum(w * e * e))


def _cells(points, block: float) -> tuple[np.ndarray, int]:
    """(block index of every point, number of blocks holding a point): the square grid of
    ``block`` d laid over the box."""
    ids = np.unique(np.floor(points / block).astype(np.int64), axis=0, return_inverse=True)[1]
    ids = ids.reshape(-1)
    return ids, int(ids.max()) + 1 if ids.size else 0


def rigid_projection(e, w, pos, radius, block: float) -> np.ndarray:
    """P e (bodies, 3) for the block-rigid subspace: per block, the energy-orthogonal projection
    on translation x, translation y and rotation about the block's centre of mass (an orthogonal
    basis about that centre, so the projection is three independent coefficients); zero on fixed
    grains and walls."""
    n = pos.shape[0]
    m = w[:n, 0]
    sel = m > 0.0
    ids, nb = _cells(pos[sel], block)
    es, m, x, r = e[:n][sel], m[sel], pos[sel], radius[sel]

    def bsum(v):
        return np.bincount(ids, weights=v, minlength=nb)

    mass = bsum(m)
    cx, cy = bsum(m * x[:, 0]) / mass, bsum(m * x[:, 1]) / mass
    dx, dy = x[:, 0] - cx[ids], x[:, 1] - cy[ids]
    ux, uy = bsum(m * es[:, 0]) / mass, bsum(m * es[:, 1]) / mass
    om = (bsum(m * (-dy * es[:, 0] + dx * es[:, 1]) + 0.5 * m * r * es[:, 2])
          / bsum(m * (dx * dx + dy * dy) + 0.5 * m * r * r))
    out = np.zeros_like(e)
    out[np.nonzero(sel)[0]] = np.stack([ux[ids] - om[ids] * dy, uy[ids] + om[ids] * dx,
                                        om[ids] * r], axis=1)
    return out


def rigid_captured(e, w, pos, radius, block: float) -> float:
    """||P e||^2 for the block-rigid subspace (``rigid_projection``)."""
    return norm2(rigid_projection(e, w, pos, radius, block), w)


def impulse_to_velocity(ci, cj, c, vel) -> sp.csr_matrix:
    """G (3 (N + 3), 2 C): the body velocity change (vx, vy, s per body) of a change of every
    contact's impulses (p_n, p_t), as ``solver._push`` applies it."""
    C = ci.shape[0]
    nx, ny = c[:, C_NX], c[:, C_NY]
    im = vel[:, V_IM]
    a = np.arange(C)
    rows, cols, vals = [], [], []
    for body, sg in ((ci.astype(np.int64), 1.0), (cj.astype(np.int64), -1.0)):
        imb = im[body]
        for comp, col, val in ((0, 2 * a, sg * imb * nx), (1, 2 * a, sg * imb * ny),
                               (0, 2 * a + 1, -sg * imb * ny), (1, 2 * a + 1, sg * imb * nx),
                               (2, 2 * a + 1, -2.0 * imb)):
            rows.append(3 * body + comp)
            cols.append(col)
            vals.append(val)
    g = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(3 * vel.shape[0], 2 * C))
    g.eliminate_zeros()
    return g


def stress_basis(ci, c, pos, radius, block: float, gradient: bool) -> sp.csr_matrix:
    """Q (2 C, k x blocks): the impulses (p_n, p_t) of every contact under a unit stress component
    (xx, yy, xy) of its block, uniform (k = 3) or also times the contact point's offset from the
    block's mean contact point over the block size (k = 9). Contact points x_i - r_i n."""
    C = ci.shape[0]
    nx, ny = c[:, C_NX], c[:, C_NY]
    i = ci.astype(np.int64)
    pt_x = pos[i, 0] - radius[i] * nx
    pt_y = pos[i, 1] - radius[i] * ny
    ids, nb = _cells(np.stack([pt_x, pt_y], axis=1), block)
    count = np.bincount(ids, minlength=nb)
    mods = [np.ones(C)]
    if gradient:
        mods += [(pt_x - (np.bincount(ids, pt_x, nb) / count)[ids]) / block,
                 (pt_y - (np.bincount(ids, pt_y, nb) / count)[ids]) / block]
    # n.sigma.n and t.sigma.n, t = (-n_y, n_x), for sigma = e_xx, e_yy, e_xy + e_yx
    comps = ((nx * nx, -nx * ny), (ny * ny, nx * ny), (2.0 * nx * ny, nx * nx - ny * ny))
    rows, cols, vals = [], [], []
    a = np.arange(C)
    for k, (pn, pt) in enumerate(comps):
        for q, mod in enumerate(mods):
            col = (k * len(mods) + q) * nb + ids
            rows += [2 * a, 2 * a + 1]
            cols += [col, col]
            vals += [pn * mod, pt * mod]
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(2 * C, len(comps) * len(mods) * nb))


def interface_basis(ci, cj, pos, block: float) -> sp.csr_matrix:
    """Q (2 C, 2 m): the impulses (p_n, p_t) of the m contacts whose bodies lie in different
    blocks (grains binned by their centres; each wall a block of its own), one column each."""
    ids = np.concatenate([_cells(pos, block)[0], -1 - np.arange(3)])  # walls: bodies n, n + 1, n + 2
    between = np.nonzero(ids[ci] != ids[cj])[0]
    m = between.size
    rows = np.concatenate([2 * between, 2 * between + 1])
    cols = np.concatenate([2 * np.arange(m), 2 * np.arange(m) + 1])
    return sp.csr_matrix((np.ones(2 * m), (rows, cols)), shape=(2 * ci.shape[0], 2 * m))


class Projector:
    """The energy-orthogonal projection on the velocities of a subspace of impulses G Q: least
    squares on the weighted rows, by a factorisation of the normal equations (a ridge of
    RIDGE x their largest diagonal entry keeps blocks whose columns do nothing solvable)."""

    def __init__(self, g, q, w, ridge: float = RIDGE):
        self.sw = np.sqrt(w.reshape(-1))
        self.a = (sp.diags(self.sw) @ (g @ q)).tocsc()
        normal = (self.a.T @ self.a).tocsc()
        ridge = ridge * max(float(normal.diagonal().max()), 1e-300)
        self.lu = spl.splu((normal + ridge * sp.identity(normal.shape[0], format="csc")).tocsc())

    def coefficients(self, e) -> np.ndarray:
        """The subspace coordinates x of P e = G Q x, for e (bodies, 3)."""
        return self.lu.solve(self.a.T @ (self.sw * e.reshape(-1)))

    def captured(self, e) -> float:
        """||e||^2 - ||e - P e||^2 for e (bodies, 3)."""
        ew = self.sw * e.reshape(-1)
        r = ew - self.a @ self.coefficients(e)
        return float(ew @ ew - r @ r)


def neighbour_pairs(w, pos, at=CORR_AT):
    """(mobile grains, their pairs closer than max(at) + 1, the pairs' distances): what
    ``correlation`` bins, the same for every field of one step."""
    from scipy.spatial import cKDTree

    n = pos.shape[0]
    sel = w[:n, 0] > 0.0
    x = pos[sel]
    pairs = cKDTree(x).query_pairs(max(at) + 1.0, output_type="ndarray")
    return sel, pairs, np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)


def correlation(e, w, pos, at=CORR_AT, pairs=None) -> list[float]:
    """C(r) = <e_i . e_j> / <|e|^2> of the translational part over pairs of mobile grains whose
    centres are r to r + 1 apart, r in ``at`` (nan where no pair is); ``pairs``: those of
    ``neighbour_pairs`` (found here if None)."""
    sel, pairs, d = neighbour_pairs(w, pos, at) if pairs is None else pairs
    v = e[: pos.shape[0]][sel, :2]
    var = float(np.mean(np.sum(v * v, axis=1)))
    prod = np.sum(v[pairs[:, 0]] * v[pairs[:, 1]], axis=1)
    out = []
    for r in at:
        m = (d >= r) & (d < r + 1.0)
        out.append(float(prod[m].mean() / var) if m.any() and var > 0.0 else float("nan"))
    return out


# -- one step ------------------------------------------------------------------------------------

def solve_step(s, caps, long: int) -> dict:
    """The prepared step of ``s`` solved to ``long`` sweeps in chunks, velocities kept at ``caps``
    (sorted, each <= long); then ``s`` takes the run's own solve (one call at solver.max_iter).
    Returns the velocities per cap (None where the solve had stopped on solver.tol before), the
    reference, the warm start and the sweeps of the run's solve."""
    p = s.params
    ci, cj = s.ci, s.cj
    perm = np.empty(ci.shape[0], np.int64)
    start = s.vel.copy()
    c, vel, st, rng = s.c.copy(), s.vel.copy(), s.status.copy(), s.rng.copy()
    kept, done, stopped = {}, 0, False
    for target in list(caps) + [long]:
        if not stopped:
            want = target - done
            it, res, _ = nlgs(ci, cj, c, st, vel, p["tol"], want, p["mode"], rng, perm,
                              p["relax"], p["prune"])
            done += int(it)
            stopped = it < want or res <= p["tol"]
        # a solve stopped on solver.tol is the reference itself from then on: no error to measure
        kept[target] = None if stopped else vel.copy()
    ref = vel.copy()
    it1, _, _ = nlgs(ci, cj, s.c, s.status, s.vel, p["tol"], p["max_iter"], p["mode"], s.rng,
                     perm, p["relax"], p["prune"])
    return dict(kept={k: kept[k] for k in caps}, ref=ref, start=start, sweeps=int(it1),
                long_sweeps=done)


def measure_step(s, caps, long: int, blocks) -> dict:
    """One step's errors, captured fractions and correlations (module docstring)."""
    sol = solve_step(s, caps, long)
    n = s.n
    w = energy_weights(s.vel, n)
    ref = sol["ref"][:, :3]
    e_ref = norm2(ref, w)
    g = impulse_to_velocity(s.ci, s.cj, s.c, s.vel)
    proj = {(space, b): Projector(g, stress_basis(s.ci, s.c, s.pos, s.radius, b,
                                                  space == "stress_grad"), w)
            for space in SPACES[1:] for b in blocks}
    pairs = neighbour_pairs(w, s.pos)
    rec = dict(sweeps=sol["sweeps"], long_sweeps=sol["long_sweeps"], error={}, captured={},
               corr_error={}, motion_rigid=[], change_rigid=[],
               corr_motion=correlation(ref, w, s.pos, pairs=pairs))
    change = ref - sol["start"][:, :3]
    e_change = norm2(change, w)
    for b in blocks:
        rec["motion_rigid"].append(rigid_captured(ref, w, s.pos, s.radius, b) / e_ref
                                   if e_ref > 0 else float("nan"))
        rec["change_rigid"].append(rigid_captured(change, w, s.pos, s.radius, b) / e_change
                                   if e_change > 0 else float("nan"))
    for k in caps:
        v = sol["kept"][k]
        if v is None:
            continue
        e = v[:, :3] - ref
        ee = norm2(e, w)
        if ee <= 0.0:
            continue
        rec["error"][k] = float(np.sqrt(ee / e_ref)) if e_ref > 0 else float("nan")
        rec["captured"][k] = {
            "rigid": [rigid_captured(e, w, s.pos, s.radius, b) / ee for b in blocks],
            **{space: [proj[space, b].captured(e) / ee for b in blocks] for space in SPACES[1:]}}
        rec["corr_error"][k] = correlation(e, w, s.pos, pairs=pairs)
    return rec


# -- an oracle two-level iteration -----------------------------------------------------------------

ORACLE_SPACES = ("plain", "stress", "stress_grad", "interface", "rigid")


def subspace_basis(space: str, s, block: float) -> sp.csr_matrix:
    """Q of an impulse subspace (``stress``, ``stress_grad``, ``interface``) for the contacts of
    ``s`` and blocks of ``block`` d."""
    if space == "interface":
        return interface_basis(s.ci, s.cj, s.pos, block)
    return stress_basis(s.ci, s.c, s.pos, s.radius, block, space == "stress_grad")


def feasible(p, mu) -> np.ndarray:
    """Impulses (C, 2) projected on their Coulomb cones: p_n >= 0, |p_t| <= mu p_n."""
    pn = np.maximum(p[:, 0], 0.0)
    return np.stack([pn, np.clip(p[:, 1], -mu * pn, mu * pn)], axis=1)


def _n_blocks(s, block: float) -> int:
    """Blocks of ``block`` d holding a mobile grain."""
    return _cells(s.pos[s.vel[: s.n, V_IM] > 0.0], block)[1]


def oracle_step(s, every: int, upto: int, long: int, blocks, ridge: float = ORACLE_RIDGE,
                feasible_only: bool = False) -> dict:
    """The prepared step of ``s`` solved from its warm start by plain NLGS and by NLGS whose
    iterate takes, every ``every`` sweeps, the best correction an impulse subspace holds: the
    energy-orthogonal projection of its velocity error against the ``long`` solve, applied to the
    impulses (p -= Q x) and through G to the velocities (v -= G Q x), so that the iterate stays a
    consistent pair (v = v_free + G p) and Gauss-Seidel goes on from it. No coarse problem picks
    a better move in the subspace (an oracle: it knows the answer), so this is the ceiling of each
    correction; the later sweeps also depend on the impulses, chosen here by least norm (module
    docstring). Errors ||v - v_ref|| / ||v_ref|| at every ``every`` sweeps up to ``upto``, after
    the correction, each subspace's dimension (``dims``, beside ``unknowns``: 2 per contact), and
    ``drift``: how far the final iterate is from a consistent pair,
    max |v - v_start - G (p - p_start)| / max |v_ref| (rounding only). The projection's ridge is
    ``ridge`` x the largest diagonal entry of its normal equations; ``feasible_only``: the corrected impulses are
    projected on their Coulomb cones (and the velocities moved with them) before the sweeps go
    on. Then ``s`` takes the run's own solve (one call at solver.max_iter)."""
    p = s.params
    ci, cj = s.ci, s.cj
    perm = np.empty(ci.shape[0], np.int64)

    def solve(c, vel, rng, sweeps):
        return nlgs(ci, cj, c, s.status.copy(), vel, p["tol"], sweeps, p["mode"], rng, perm,
                    p["relax"], p["prune"])

    ref_v = s.vel.copy()
    solve(s.c.copy(), ref_v, s.rng.copy(), long)
    ref = ref_v[:, :3]
    w = energy_weights(s.vel, s.n)
    e_ref = norm2(ref, w)
    g = impulse_to_velocity(ci, cj, s.c, s.vel)
    points = list(range(every, upto + 1, every))
    errors, dims, drift = {}, {}, {}
    scale = max(float(np.abs(ref).max()), 1e-300)
    every_contact = None  # the rigid variants' impulses: least squares over all the contacts
    for space in ORACLE_SPACES:
        for b in [None] if space == "plain" else blocks:
            if space == "rigid":
                if every_contact is None:
                    q = sp.identity(2 * ci.shape[0], format="csr")
                    every_contact = Projector(g, q, w, ridge)
                proj = every_contact
            else:
                q = None if b is None else subspace_basis(space, s, b)
                proj = None if q is None else Projector(g, q, w, ridge)
            c, vel, rng = s.c.copy(), s.vel.copy(), s.rng.copy()
            errs, stopped = [], False
            for _ in points:
                if not stopped:
                    it, res, _ = solve(c, vel, rng, every)
                    stopped = it < every or res <= p["tol"]
                    if proj is not None and not stopped:
                        target = vel[:, :3] - ref
                        if space == "rigid":
                            target = rigid_projection(target, w, s.pos, s.radius, b)
                        dp = (q @ proj.coefficients(target)).reshape(-1, 2)
                        if feasible_only:
                            dp = c[:, IMPULSE] - feasible(c[:, IMPULSE] - dp, c[:, C_MU])
                        c[:, IMPULSE] -= dp
                        vel[:, :3] -= (g @ dp.reshape(-1)).reshape(-1, 3)
                errs.append(float(np.sqrt(norm2(vel[:, :3] - ref, w) / e_ref)) if e_ref > 0
                            else float("nan"))
            name = "plain" if b is None else f"{space}/{b:g}"
            errors[name] = errs
            if space == "rigid":  # 3 per block; q is every contact's impulses
                dims[name] = 3 * _n_blocks(s, b)
            else:
                dims[name] = 0 if q is None else int(q.shape[1])
            # the iterate stays a consistent pair: v - v_start = G (p - p_start)
            dv = g @ (c[:, IMPULSE] - s.c[:, IMPULSE]).reshape(-1)
            drift[name] = float(np.abs((vel - s.vel)[:, :3].reshape(-1) - dv).max() / scale)
    it1, _, _ = nlgs(ci, cj, s.c, s.status, s.vel, p["tol"], p["max_iter"], p["mode"], s.rng,
                     perm, p["relax"], p["prune"])
    return dict(points=points, errors=errors, dims=dims, unknowns=2 * int(ci.shape[0]),
                drift=drift, sweeps=int(it1))


def summarize_oracle(steps: list[dict], cap: int) -> dict:
    """Over the steps whose run's solve met its cap: per variant the median error at every
    point, and the median of the sweeps from which its error is at most plain NLGS's at the cap
    (inf where it never is within the points)."""
    capped = [r for r in steps if r["sweeps"] >= cap]
    out = dict(steps=len(steps), capped=len(capped), variants={})
    if not capped:
        return out
    points = np.array(capped[0]["points"])
    k_cap = int(np.searchsorted(points, cap))
    for name in capped[0]["errors"]:
        reach = []
        for r in capped:
            err = np.array(r["errors"][name])
            ok = np.nonzero(err <= r["errors"]["plain"][min(k_cap, len(points) - 1)])[0]
            reach.append(float(points[ok[0]]) if ok.size else float("inf"))
        out["variants"][name] = dict(
            error=[float(x) for x in np.median([r["errors"][name] for r in capped], axis=0)],
            reach_plain_cap=float(np.median(reach)),
            dim_fraction=float(np.median([r["dims"][name] / r["unknowns"] for r in capped])))
    return out


def oracle_study(run_path, frames, steps: int, every: int, long: int, blocks, warm: int = 10,
                 ridge: float = ORACLE_RIDGE, feasible_only: bool = False, progress: bool = True,
                 out=None) -> dict:
    """``oracle_step`` over S steps from each frame, up to the run's cap."""
    from tqdm.auto import tqdm

    out = sys.stdout if out is None else out
    rows = []
    with tqdm(total=len(frames) * steps, unit="step", desc="oracle", disable=not progress,
              file=sys.stderr) as bar:
        for f, cfg, theta, s in frame_systems(run_path, frames, warm, bar):
            cap, dth = cfg.solver.max_iter, cfg.protocol.tilt_per_step_deg
            recs, t0 = [], time.perf_counter()
            for k in range(steps):
                prepare_step(s, theta + k * dth, dth)
                recs.append(oracle_step(s, every, cap, long, blocks, ridge, feasible_only))
                finish_step(s)
                bar.update(1)
            summ = summarize_oracle(recs, cap)
            rows.append(dict(frame=int(f), theta=theta, cap=cap, seconds=time.perf_counter() - t0,
                             summary=summ, steps=recs))
            for name, v in summ["variants"].items():
                print(f"frame {f:4d} ({theta:5.2f} deg), {summ['capped']}/{summ['steps']} steps "
                      f"capped: {name:15s} ({100 * v['dim_fraction']:.3g}% of the unknowns) "
                      f"error at {every}: {100 * v['error'][0]:.3g}%, at {cap}: "
                      f"{100 * v['error'][-1]:.3g}%; reaches plain NLGS's error at {cap} at "
                      f"{v['reach_plain_cap']:g} sweeps", file=out, flush=True)
    return dict(kind="oracle", run=str(run_path), steps=steps, every=every, long=long,
                warm=warm, blocks=list(blocks), ridge=ridge, feasible_only=feasible_only, rows=rows)


# -- a frame and the study -------------------------------------------------------------------------

def _med(xs) -> float:
    xs = np.asarray([x for x in xs if x is not None], float)
    return float(np.nanmedian(xs)) if xs.size and np.isfinite(xs).any() else float("nan")


def summarize(steps: list[dict], caps, blocks) -> dict:
    """Medians over the steps (each cap over the steps with an error there)."""
    out = dict(steps=len(steps), sweeps=_med([r["sweeps"] for r in steps]),
               motion_rigid=[_med([r["motion_rigid"][q] for r in steps]) for q in range(len(blocks))],
               change_rigid=[_med([r["change_rigid"][q] for r in steps]) for q in range(len(blocks))],
               corr_motion=[_med([r["corr_motion"][q] for r in steps]) for q in range(len(CORR_AT))],
               caps={})
    for k in caps:
        have = [r for r in steps if k in r["error"]]
        if not have:
            continue
        out["caps"][k] = dict(
            steps=len(have), error=_med([r["error"][k] for r in have]),
            captured={space: [_med([r["captured"][k][space][q] for r in have])
                              for q in range(len(blocks))] for space in SPACES},
            corr_error=[_med([r["corr_error"][k][q] for r in have]) for q in range(len(CORR_AT))])
    return out


def study(run_path, frames, steps: int, caps, long: int, blocks, warm: int = 10,
          progress: bool = True, out=None) -> dict:
    """The measurement of the module docstring: one row per frame (a line each to ``out``,
    default stdout)."""
    from tqdm.auto import tqdm

    out = sys.stdout if out is None else out
    rows = []
    with tqdm(total=len(frames) * steps, unit="step", desc="coarse", disable=not progress,
              file=sys.stderr) as bar:
        for f, cfg, theta, s in frame_systems(run_path, frames, warm, bar):
            cap, dth = cfg.solver.max_iter, cfg.protocol.tilt_per_step_deg
            ks = sorted({int(k) for k in caps if k < long} | ({cap} if cap < long else set()))
            recs, t0 = [], time.perf_counter()
            for k in range(steps):
                prepare_step(s, theta + k * dth, dth)
                recs.append(measure_step(s, ks, long, blocks))
                finish_step(s)
                bar.update(1)
            summ = summarize(recs, ks, blocks)
            rows.append(dict(frame=int(f), theta=theta, cap=cap, caps=ks,
                             seconds=time.perf_counter() - t0, summary=summ, steps=recs))
            print(_line(f, theta, summ, cap, blocks), file=out, flush=True)
    return dict(run=str(run_path), steps=steps, long=long, warm=warm, blocks=list(blocks),
                corr_at=list(CORR_AT), rows=rows)


def _line(f, theta, m, cap, blocks) -> str:
    q = blocks.index(10) if 10 in blocks else 0
    head = f"frame {f:4d} ({theta:5.2f} deg), {m['steps']} steps, run's solve {m['sweeps']:.0f} sweeps"
    if cap not in m["caps"]:
        return head + f": no step still moving at its cap of {cap}"
    c = m["caps"][cap]
    err = ", ".join(f"{k}: {100 * v['error']:.3g}%" for k, v in m["caps"].items())
    return (f"{head}; error {err}; at {cap} ({c['steps']} steps) blocks of {blocks[q]} d capture "
            f"rigid {100 * c['captured']['rigid'][q]:.3g}%, stress {100 * c['captured']['stress'][q]:.3g}%, "
            f"stress_grad {100 * c['captured']['stress_grad'][q]:.3g}% of the error's energy "
            f"(rigid, of the motion: {100 * m['motion_rigid'][q]:.3g}%); error correlation "
            f"{c['corr_error'][0]:.2f} at {CORR_AT[0]} d, {c['corr_error'][-1]:.2f} at {CORR_AT[-1]} d "
            f"(motion {m['corr_motion'][0]:.2f}, {m['corr_motion'][-1]:.2f})")


# -- the chart -----------------------------------------------------------------------------------

def plot(results: list[dict], path) -> None:
    """Three panels, medians over the steps: the error energy each subspace captures at the
    run's cap against the block size (and, for rigid blocks, the motion's), and the correlation
    of the error and of the motion against distance. A colour per frame angle, a marker per run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.3))
    thetas = sorted({round(r["theta"], 2) for res in results for r in res["rows"]})
    markers = "osD^v"
    for r_i, res in enumerate(results):
        name = Path(res["run"]).stem
        blocks = np.array(res["blocks"], float)
        for row in res["rows"]:
            col = f"C{thetas.index(round(row['theta'], 2))}"
            m = row["summary"]
            lab = f"{row['theta']:.0f} deg ({name})"
            mk = markers[r_i % len(markers)]
            cap = row["cap"]
            if cap in m["caps"] or str(cap) in m["caps"]:
                c = m["caps"].get(cap, m["caps"].get(str(cap)))
                axes[0].plot(blocks, c["captured"]["rigid"], "-" + mk, color=col, label=lab)
                axes[1].plot(blocks, c["captured"]["stress"], "-" + mk, color=col, label=f"{lab} uniform")
                axes[1].plot(blocks, c["captured"]["stress_grad"], "--" + mk, color=col,
                             label=f"{lab} linear", mfc="none")
                axes[2].plot(np.array(res["corr_at"]) + 0.5, c["corr_error"], "-" + mk, color=col,
                             label=f"error, {lab}")
            axes[0].plot(blocks, m["motion_rigid"], ":" + mk, color=col, mfc="none",
                         label=f"the motion itself, {lab}")
            axes[2].plot(np.array(res["corr_at"]) + 0.5, m["corr_motion"], ":" + mk, color=col,
                         mfc="none", label=f"motion, {lab}")
    for ax in axes[:2]:
        ax.set_xlabel("block size [d]")
        ax.set_ylim(0, 1)
        ax.invert_xaxis()
    axes[0].set_ylabel("fraction of the error energy in the subspace")
    axes[0].set_title("rigid blocks (item 4), error at the cap;\ndotted: the step's motion v_ref", fontsize=10)
    axes[1].set_title("block stress (uniform, linear), error at the cap", fontsize=10)
    axes[2].set_title("correlation of velocities (translation)", fontsize=10)
    axes[2].set_xlabel("distance between grain centres [d]")
    axes[2].axhline(0, color="0.6", lw=0.6)
    for ax in axes:
        ax.legend(fontsize=6.5)
    fig.suptitle("The most any coarse correction could remove of NLGS's error at the run's cap "
                 "(energy norm; error against a 20 000-sweep solve of the same step)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


PLOTTED = ("plain", "rigid", "interface")  # the stress variants gain less (docs/performance-log.md)


def plot_oracle(results: list[dict], path) -> None:
    """A panel per frame angle: the median error against the sweeps (the capped steps) of plain
    NLGS (black) and of the variants in PLOTTED, a line style per run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    thetas = sorted({round(r["theta"], 2) for res in results for r in res["rows"]})
    fig, axes = plt.subplots(1, len(thetas), figsize=(4.8 * len(thetas), 4.2), squeeze=False)
    styles = ("-", "--", ":", "-.")
    for r_i, res in enumerate(results):
        name = Path(res["run"]).stem
        for row in res["rows"]:
            ax = axes[0, thetas.index(round(row["theta"], 2))]
            m = row["summary"]
            if not m["variants"]:
                continue
            x = row["steps"][0]["points"]
            shown = [v for v in m["variants"] if v.split("/")[0] in PLOTTED]
            for v_i, var in enumerate(shown):
                ax.plot(x, m["variants"][var]["error"], styles[r_i % len(styles)],
                        color="k" if var == "plain" else f"C{v_i - 1}", label=f"{var} ({name})")
            ax.set_title(f"{row['theta']:.2f} deg: {m['capped']} capped steps", fontsize=10)
    for ax in axes[0]:
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("NLGS sweeps in the step")
        ax.legend(fontsize=6.5)
    axes[0, 0].set_ylabel("velocity error against the long solve (energy norm)")
    blocks = ", ".join(f"{b:g}" for b in results[0]["blocks"]) if results else ""
    fig.suptitle(f"NLGS with an oracle coarse correction every {results[0]['every'] if results else ''} "
                 f"sweeps (the best element of the subspace; blocks of {blocks} d)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# -- command line --------------------------------------------------------------------------------

def _fail(msg: str):
    raise SystemExit(f"python -m tiltpile.bench.coarse: error: {msg}")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(prog="python -m tiltpile.bench.coarse",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("run", nargs="?")
    ap.add_argument("--frames", type=int, nargs="+")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--caps", type=int, nargs="+", default=list(DEFAULT_CAPS))
    ap.add_argument("--long", type=int, default=20_000)
    ap.add_argument("--blocks", type=float, nargs="+", default=list(DEFAULT_BLOCKS))
    ap.add_argument("--warm", type=int, default=10)
    ap.add_argument("--json", help="write the rows (every step's numbers) to this file")
    ap.add_argument("--chart", help="draw the chart (PNG) of this measurement, or of --plot's files")
    ap.add_argument("--plot", nargs="+", metavar="JSON", help="chart earlier --json files, no measurement")
    ap.add_argument("--oracle", type=int, metavar="K",
                    help="instead: NLGS with the oracle correction of each impulse subspace every "
                         "K sweeps, against plain NLGS (``oracle_step``)")
    ap.add_argument("--ridge", type=float, default=ORACLE_RIDGE,
                    help=f"--oracle: the projection's relative ridge (default {ORACLE_RIDGE:g})")
    ap.add_argument("--feasible", action="store_true",
                    help="--oracle: project each corrected impulse on its Coulomb cone")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    a = ap.parse_args(argv)
    if a.plot:
        if not a.chart:
            _fail("--plot needs --chart PNG")
        results = read_results(a.plot, _fail)
        oracle = [r.get("kind") == "oracle" for r in results]
        if any(oracle) and not all(oracle):
            _fail("--plot: give the files of one kind (all --oracle or none)")
        (plot_oracle if all(oracle) else plot)(results, a.chart)
        return dict(results=results)
    if not a.run or not a.frames:
        _fail("give a run file and --frames (or --plot JSON ... --chart PNG)")
    if a.steps < 1 or a.long < 1 or a.warm < 0 or min(a.caps) < 1 or not min(a.blocks) > 0:
        _fail("--steps, --long and --caps must be >= 1, --warm >= 0 and --blocks > 0")
    if a.oracle is not None and a.oracle < 1:
        _fail("--oracle must be >= 1")
    if not a.ridge > 0:
        _fail("--ridge must be > 0")
    check_outputs((a.json, a.chart), _fail)
    check_run(a.run, a.frames, _fail)
    blocks = [int(b) if float(b).is_integer() else float(b) for b in a.blocks]
    if a.oracle is not None:
        result = oracle_study(a.run, a.frames, a.steps, a.oracle, a.long, blocks, a.warm,
                              a.ridge, a.feasible, progress=not a.quiet)
    else:
        result = study(a.run, a.frames, a.steps, a.caps, a.long, blocks, a.warm,
                       progress=not a.quiet)
    if a.json:
        Path(a.json).write_text(json.dumps(result))
    if a.chart:
        (plot_oracle if a.oracle is not None else plot)([result], a.chart)
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
