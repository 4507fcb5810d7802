"""Nonlinear Gauss-Seidel (NLGS) over contacts with the exact local 2D Coulomb solution.

Data (all plain arrays, updated in place):

``vel`` (N + 3, 4)  per body: vx, vy, s = r * omega (rim speed), 1/m. Rows N..N+2 are the walls
                    (zero velocity, zero inverse mass), so one kernel serves every contact.
``ci, cj`` (C,)     body indices of each contact.
``c`` (C, 8)        per contact: nx, ny (unit normal, pointing from body j to grain i),
                    b = gap / dt, mu, 1/W_nn, 1/W_tt, p_n, p_t (impulses over the step).
``status`` (C,)     int8: 0 open (p_n = 0), 1 sticking, 2 sliding (|p_t| = mu p_n).

Local kinematics. With t = (-n_y, n_x), the relative velocity of grain i against body j at the
contact point is u_n = (v_i - v_j) . n and u_t = (v_i - v_j) . t - (s_i + s_j). An impulse
P = p_n n + p_t t on i (and -P on j) changes them through the Delassus matrix W, which for disks
(I = m r^2 / 2) is diagonal: W_nn = 1/m_i + 1/m_j, W_tt = 3 (1/m_i + 1/m_j), W_nt = 0.

Contact law (Moreau-Jean, theta = 1, zero restitution). The end-of-step gap g + dt u_n must be
non-negative, unilaterally: (u_n + b >= 0) _|_ (p_n >= 0) with b = g / dt, so a contact that is
open may close exactly within the step and an overlap left by the linearised gap is pushed out
in one step instead of drifting. Friction: |p_t| <= mu p_n, sticking (u_t = 0) inside the cone
and sliding against u_t on its edge. Because W is diagonal the local problem is solved exactly
in closed form: p_n first, then p_t as the sticking value clipped to the cone.

Sweep orders (``mode``): 0 forward, over the contacts sorted by key (particle id of grain i,
then j; grains are numbered bottom-up, so the sweep runs roughly bottom-up); 1 alternating
forward/backward in that order (a symmetric Gauss-Seidel); 2 random order, reshuffled every
sweep (Unger & Kertesz, PRE 67, 2003; Jean 1999), from a checkpointable RNG; 3 interleaved:
forward over the list in the order of ``detect.interleave``, stored so at every rebuild, which
keeps each contact within a few places of its key order but puts no body twice within 8
consecutive places. Forward and interleaved sweep the stored list (``_sweep_stored``): in key
order consecutive updates share grain i and wait for each other, in interleaved order the CPU
overlaps them (same sweeps per step, less time per sweep; ``docs/performance.md``).

Over-relaxation (``relax`` = omega in (0, 2), projected SOR): each local solve moves the impulse
omega times the plain correction, p_n <- max(0, p_n - omega W_nn^-1 (u_n + b)), then
p_t <- clip(p_t - omega W_tt^-1 u_t, +-mu p_n), i.e. the over-relaxed value projected onto the
Coulomb cone. omega = 1 is the plain NLGS (bit for bit). The first sweep of every step is plain
(a lone contact, e.g. a disk landing on the floor, is then solved exactly in one sweep instead of
oscillating towards it by factors 1 - omega). In a pile the forces relax diffusively under
Gauss-Seidel; omega > 1 shortens that, and omega >= 1.7 can oscillate between sticking and
sliding states (what it gains: ``notes/performance-log.md``, "Optional SOR").

Pruned sweeps (``prune``; ``solver.prune``, on by default). Many candidate contacts are open
with a gap that nothing in the pile closes within the step (u_n + b > PRUNE_MARGIN); their local
solve gives p = 0 and changes nothing, yet costs a full update in every sweep. A step still
unconverged after PRUNE_AFTER sweeps sweeps a compacted list without them, with a full sweep
every PRUNE_EVERY sweeps and at the cap, and ends on the compacted list only if none of them
would now overlap. The sweeps are then those of the full list bit for bit, as long as none of the
left-out contacts closes during the step (``tests/sim/test_pruned_sweeps.py``). A left-out
contact that would overlap at the end is caught and the step goes on with full sweeps; one that
closes and opens again in between is not. Either way the result is as converged, but the iterates
differ from the full sweeps' from then on. What it saves and where it was checked:
``notes/performance-log.md``, "Pruned sweeps".

Convergence: the relative L2 change of the impulses over one sweep, divided by omega,
    r = sqrt(sum |p^k - p^(k-1)|^2 / sum |p^k|^2) / omega,
(the change per sweep of an over-relaxed solve is omega times the plain local correction, so
dividing by omega keeps r the size of the plain correction), stops when r <= tol (LMGC90's
'Quad' norm in spirit; tol 1e-4 is the usual setting, see Radjai & Richefeu, Mech. Mater. 41,
2009) or after ``max_iter`` sweeps. With no load at all
(sum |p|^2 = 0) r = 0. A small r after a sweep is not a small error when forces relax
diffusively; the creep and convergence tests measure that error directly.
"""

from __future__ import annotations

import math

import numpy as np

from tiltpile.sim.jit import njit
from tiltpile.sim.rng import shuffle

# columns of the contact array ``c`` (C, N_CONTACT_COLUMNS) and of the body array ``vel``
# (N + 3, 4), as in the module docstring; ``c[:, IMPULSE]`` is the pair (p_n, p_t). Module-level
# integers: numba compiles them in as constants.
C_NX, C_NY, C_B, C_MU, C_IWN, C_IWT, C_PN, C_PT = range(8)
N_CONTACT_COLUMNS = 8
IMPULSE = slice(C_PN, C_PT + 1)
V_X, V_Y, V_S, V_IM = range(4)
N_BODY_COLUMNS = 4

FORWARD, ALTERNATING, RANDOM, INTERLEAVED = 0, 1, 2, 3
_U = np.uint64  # unsigned indices: numba emits no negative-index wrap-around for them
SWEEPS = {"forward": FORWARD, "alternating": ALTERNATING, "random": RANDOM, "interleaved": INTERLEAVED}

OPEN, STICK, SLIDE = 0, 1, 2

# Pruned sweeps (``nlgs(..., prune=True)``, ``_pruned_sweeps``): after PRUNE_AFTER full sweeps a
# step that has not converged sweeps only the contacts that can act, with a full sweep every
# PRUNE_EVERY sweeps and as the last one at the cap. PRUNE_MARGIN [d / sqrt(d/g)]: an open contact
# is left out when u_n + b > PRUNE_MARGIN (a gap of more than 0.01 d that is not closing, at
# dt = 0.01; 100 g dt). Why 1.0 and not 0.1: notes/performance-log.md, "Pruned sweeps".
PRUNE_AFTER = 20
PRUNE_EVERY = 100
PRUNE_MARGIN = 1.0


@njit
def apply_impulses(ci, cj, c, vel):
    """Add every contact's current impulse (c[:, IMPULSE]) to the body velocities (warm start)."""
    for a in range(ci.shape[0]):
        _push(vel, ci[a], cj[a], c[a, C_NX], c[a, C_NY], c[a, C_PN], c[a, C_PT])


@njit(inline="always")
def _push(vel, i, j, nx, ny, dpn, dpt):
    px = dpn * nx - dpt * ny
    py = dpn * ny + dpt * nx
    imi = vel[i, V_IM]
    imj = vel[j, V_IM]
    vel[i, V_X] += imi * px
    vel[i, V_Y] += imi * py
    vel[i, V_S] -= 2.0 * imi * dpt
    vel[j, V_X] -= imj * px
    vel[j, V_Y] -= imj * py
    vel[j, V_S] -= 2.0 * imj * dpt


@njit
def nlgs(ci, cj, c, status, vel, tol, max_iter, mode, rng_state, perm, relax=1.0, prune=False):
    """Sweep until the relative impulse change is <= tol or ``max_iter`` sweeps.

    Arrays as in the module docstring (updated in place): ci, cj (C,); c (C, 8); status (C,) int8;
    vel (N + 3, 4). mode: FORWARD, ALTERNATING, RANDOM or INTERLEAVED; rng_state the
    checkpointable RNG of the random order; relax the over-relaxation omega in (0, 2).
    ``perm`` (C,) int64 is scratch for the random and alternating orders. ``prune`` (forward and
    interleaved sweeps): past ``PRUNE_AFTER`` sweeps, sweep only the contacts that can act
    (``_pruned_sweeps``). Returns (sweeps, residual, local solves made: sweeps x contacts
    unless pruned). ``status`` is set from the final impulses (``set_status``).
    """
    nc = ci.shape[0]
    if nc == 0:
        return 0, 0.0, 0
    cf = c.reshape(c.size)
    vf = vel.reshape(vel.size)
    res = 0.0
    it = 0
    updates = 0
    while it < max_iter:
        # the first sweep is plain: an isolated contact is solved exactly by it, and over-relaxing
        # a contact whose local solve is already exact only makes it oscillate (x (1 - omega))
        w = 1.0 if it == 0 else relax
        if mode == RANDOM:
            if it == 0:
                for k in range(nc):
                    perm[k] = k
            shuffle(rng_state, perm[:nc])
            num, den = _sweep_perm(ci, cj, c, vel, perm, w)
        elif mode == ALTERNATING:
            for k in range(nc):
                perm[k] = nc - 1 - k if it % 2 == 1 else k
            num, den = _sweep_perm(ci, cj, c, vel, perm, w)
        else:
            num, den = _sweep_stored(ci, cj, cf, vf, w)
        it += 1
        updates += nc
        res = _relative_change(num, den, w)
        if res <= tol:
            break
        if prune and (mode == FORWARD or mode == INTERLEAVED) and PRUNE_AFTER <= it < max_iter - 1:
            it0 = it
            it, res, done, m = _pruned_sweeps(ci, cj, c, vel, tol, it,
                                              min(max_iter - 1, it + PRUNE_EVERY - 1), relax)
            updates += (it - it0) * m
            if done:
                break
    set_status(c, status)
    return it, res, updates


@njit
def _pruned_sweeps(ci, cj, c, vel, tol, it, last, w):
    """Sweeps over the contacts that can act, from sweep ``it`` up to sweep ``last`` at most.

    Left out: open contacts (p_n = 0) whose end-of-step gap rate u_n + b exceeds PRUNE_MARGIN at
    the start. As long as u_n + b >= 0 stays true for them their local solve gives p = 0 and a
    full sweep would change nothing there, so these sweeps are bit for bit those of the full list
    (the residual's sums only miss zeros). The list keeps the stored order.

    Returns (it, res, done, m): done when the residual reached tol and every contact left out
    still has u_n + b >= 0 (else, or at ``last``, the caller goes on with a full sweep, which
    checks every contact again); m contacts were swept. Impulses are copied back either way.
    """
    nc = ci.shape[0]
    pci = np.empty(nc, np.int32)
    pcj = np.empty(nc, np.int32)
    pc = np.empty((nc, N_CONTACT_COLUMNS))
    idx = np.empty(nc, np.int64)
    out = np.empty(nc, np.int64)
    m = 0
    n_out = 0
    for a in range(nc):
        if c[a, C_PN] == 0.0 and _gap_rate(ci, cj, c, vel, a) > PRUNE_MARGIN:
            out[n_out] = a
            n_out += 1
            continue
        idx[m] = a
        pci[m] = ci[a]
        pcj[m] = cj[a]
        for k in range(8):
            pc[m, k] = c[a, k]
        m += 1
    pcf = pc[:m].reshape(8 * m)
    vf = vel.reshape(vel.size)
    res = np.inf
    while it < last:
        num, den = _sweep_stored(pci[:m], pcj[:m], pcf, vf, w)
        it += 1
        res = _relative_change(num, den, w)
        if res <= tol:
            break
    for k in range(m):
        c[idx[k], C_PN] = pc[k, C_PN]
        c[idx[k], C_PT] = pc[k, C_PT]
    done = res <= tol
    if done:  # would a full sweep change a contact left out?
        for k in range(n_out):
            if _gap_rate(ci, cj, c, vel, out[k]) < 0.0:
                done = False
                break
    return it, res, done, m


@njit(inline="always")
def _relative_change(num, den, w):
    """The stopping residual of a sweep from its sums (module docstring, "Convergence")."""
    if den > 0.0:
        return math.sqrt(num / den) / w
    return 0.0 if num == 0.0 else np.inf


@njit(inline="always")
def _gap_rate(ci, cj, c, vel, a):
    """u_n + b of contact ``a``: how fast its end-of-step gap opens (< 0: it would overlap)."""
    i = ci[a]
    j = cj[a]
    return (vel[i, V_X] - vel[j, V_X]) * c[a, C_NX] + (vel[i, V_Y] - vel[j, V_Y]) * c[a, C_NY] + c[a, C_B]


@njit
def _sweep_stored(ci, cj, cf, vf, w):
    """One sweep over the contacts in their stored order (forward and interleaved sweeps).

    ci, cj (C,) body indices; cf = c.ravel() (8 C,), vf = vel.ravel() (4 (N + 3),), updated in
    place; w the relaxation. Returns (sum |dp|^2, sum |p|^2) over the sweep. This is the sweep
    the presets run (``solver.sweep`` forward or interleaved); its local solve is the contact
    law of the module docstring, the same as ``_local_solution``'s.

    Written for the compiler: flat views with unsigned indices carry no negative-index
    wrap-around code, the columns are the module's named integers (folded in as constants: the
    machine code is that of bare numbers), and the clip to the cone is min/max instead of branches, so each update is
    one chain of dependent operations and the sweep is as fast as the *order* lets consecutive
    updates overlap (``interleave``). The local solve is written out here rather than shared with
    ``_local_solution`` (random and alternating sweeps, ``natural_residual``) because an inlined
    helper returning a tuple made the sweep much slower (``docs/performance.md``).
    """
    nc = _U(ci.shape[0])
    num = 0.0
    den = 0.0
    for a in range(nc):
        i = _U(N_BODY_COLUMNS) * _U(ci[a])
        j = _U(N_BODY_COLUMNS) * _U(cj[a])
        b = _U(N_CONTACT_COLUMNS) * a
        nx = cf[b + _U(C_NX)]
        ny = cf[b + _U(C_NY)]
        pn = cf[b + _U(C_PN)]
        pt = cf[b + _U(C_PT)]
        dvx = vf[i + _U(V_X)] - vf[j + _U(V_X)]
        dvy = vf[i + _U(V_Y)] - vf[j + _U(V_Y)]
        un = dvx * nx + dvy * ny
        ut = -dvx * ny + dvy * nx - (vf[i + _U(V_S)] + vf[j + _U(V_S)])
        # u without this contact's own impulse is u - W p; the local solution in closed form,
        # p_n projected on p_n >= 0, then p_t on the cone |p_t| <= mu p_n (open: p_t = 0)
        pn_new = max(0.0, pn - (un + cf[b + _U(C_B)]) * (cf[b + _U(C_IWN)] * w))
        lim = cf[b + _U(C_MU)] * pn_new
        pt_new = min(lim, max(-lim, pt - ut * (cf[b + _U(C_IWT)] * w)))
        dpn = pn_new - pn
        dpt = pt_new - pt
        px = dpn * nx - dpt * ny
        py = dpn * ny + dpt * nx
        imi = vf[i + _U(V_IM)]
        imj = vf[j + _U(V_IM)]
        vf[i + _U(V_X)] += imi * px
        vf[i + _U(V_Y)] += imi * py
        vf[i + _U(V_S)] -= 2.0 * imi * dpt
        vf[j + _U(V_X)] -= imj * px
        vf[j + _U(V_Y)] -= imj * py
        vf[j + _U(V_S)] -= 2.0 * imj * dpt
        cf[b + _U(C_PN)] = pn_new
        cf[b + _U(C_PT)] = pt_new
        num += dpn * dpn + dpt * dpt
        den += pn_new * pn_new + pt_new * pt_new
    return num, den


@njit(inline="always")
def _local_solution(ci, cj, c, vel, a, w):
    """The local solution (p_n, p_t) of contact ``a`` given the current velocities, moved ``w``
    times the plain correction, on 2D arrays: the random and alternating sweeps and
    ``natural_residual`` use it; the presets' sweep, ``_sweep_stored``, writes the same law out
    on flat arrays (``tests/sim/test_solver.py`` holds the two equal)."""
    i = ci[a]
    j = cj[a]
    nx = c[a, C_NX]
    ny = c[a, C_NY]
    dvx = vel[i, V_X] - vel[j, V_X]
    dvy = vel[i, V_Y] - vel[j, V_Y]
    un = dvx * nx + dvy * ny
    ut = -dvx * ny + dvy * nx - (vel[i, V_S] + vel[j, V_S])
    pn_new = max(0.0, c[a, C_PN] - (un + c[a, C_B]) * (c[a, C_IWN] * w))
    lim = c[a, C_MU] * pn_new
    return pn_new, min(lim, max(-lim, c[a, C_PT] - ut * (c[a, C_IWT] * w)))


@njit
def _sweep_perm(ci, cj, c, vel, perm, w):
    """One sweep in the order ``perm`` (random and alternating sweeps)."""
    num = 0.0
    den = 0.0
    for k in range(ci.shape[0]):
        a = perm[k]
        pn_new, pt_new = _local_solution(ci, cj, c, vel, a, w)
        dpn = pn_new - c[a, C_PN]
        dpt = pt_new - c[a, C_PT]
        _push(vel, ci[a], cj[a], c[a, C_NX], c[a, C_NY], dpn, dpt)
        c[a, C_PN] = pn_new
        c[a, C_PT] = pt_new
        num += dpn * dpn + dpt * dpt
        den += pn_new * pn_new + pt_new * pt_new
    return num, den


@njit
def set_status(c, status):
    """Contact states from the impulses: open (p_n = 0), sliding (|p_t| = mu p_n: the local
    solve clipped p_t to exactly this product), else sticking."""
    for a in range(c.shape[0]):
        pn = c[a, C_PN]
        if pn == 0.0:
            status[a] = OPEN
        elif abs(c[a, C_PT]) == c[a, C_MU] * pn:
            status[a] = SLIDE
        else:
            status[a] = STICK


def empty_contacts():
    """Zero-length contact arrays of the kernel dtypes."""
    return (np.empty(0, np.int32), np.empty(0, np.int32), np.empty(0, np.int64),
            np.empty((0, N_CONTACT_COLUMNS)), np.empty(0, np.int8))


@njit
def natural_residual(ci, cj, c, vel):
    """The contact law's residual at the current impulses, independent of how they were found.

    For every contact the exact local solution p_loc (plain, relax = 1) is computed from the
    current velocities *without* applying it (a Jacobi pass); returns
    sqrt(sum |p_loc - p|^2 / sum |p|^2), zero exactly when every contact satisfies Signorini and
    Coulomb given all the others. Unlike the per-sweep change that stops ``nlgs`` it does not
    depend on the sweep order or the relaxation factor, so it compares solvers at equal accuracy.
    """
    num = 0.0
    den = 0.0
    for a in range(ci.shape[0]):
        pn = c[a, C_PN]
        pt = c[a, C_PT]
        pn_new, pt_new = _local_solution(ci, cj, c, vel, a, 1.0)
        num += (pn_new - pn) ** 2 + (pt_new - pt) ** 2
        den += pn * pn + pt * pt
    return _relative_change(num, den, 1.0)

