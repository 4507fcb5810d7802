"""One Moreau-Jean time step (theta = 1), and ``advance`` over many steps in one compiled call.

A step from t to t + dt, with gravity g(theta) = (sin theta, -cos theta) (g = 1):

1. free velocities  v* = v + dt g for mobile grains (no other body force: no cohesion,
   no rolling resistance);
2. if a grain could leave the region where the candidate list is valid -- its displacement since
   the last build plus dt |v*| exceeds alert / 2 -- rebuild the list (``detect``) and carry the
   impulses over by particle pair;
3. contact geometry at the start of the step: unit normal n, gap g, b = g / dt (for an overlap,
   g < 0, b = min(0, g + slop) / dt: see "Overlap slop" below);
4. warm start: the impulses of the previous step are applied to v*;
5. NLGS until converged (``solver``): velocities v(t + dt) and impulses;
6. positions x += dt v(t + dt), rotations phi += dt s / r (theta = 1: implicit Euler on
   positions, first order, dissipative, no energy drift).

Per step ``advance`` records: NLGS sweeps and final residual, the largest overlap at the start of
the step (max(-g), 0 if none), the kinetic energy of mobile grains, the work of gravity over the
step (dt sum_i m_i g . v_i(t + dt), exactly the work along the implicit-Euler displacement), and
whether a grain moved farther than alert / 2 since the last build after the step (a contact could
have been missed: the time step is too large for the alert distance).

Overlap slop (``slop``: solver.overlap_slop, 1e-6 d in every preset; 0, the plain gap term, for a
System built without it). With b = g / dt every overlap is pushed out in full in the next step.
An NLGS stopped at its tolerance leaves velocity errors of about tol; integrated, they become
tiny overlaps, which the next step's gap term turns back into a velocity target of the same size,
so each step restarts from an error of about tol and spends its sweeps removing it again.
Overlaps up to ``slop`` are left alone (b = 0) and deeper ones are pushed back to ``slop``, not
to zero -- the dead zone of Box2D's "linear slop" (E. Catto) applied to Moreau-Jean's gap term;
overlaps then stay <= ~1.1 slop (tests/sim/test_overlap_slop.py). The price is a small drift of a
pile below its failure angle, which a tighter tol buys back. What it saves and costs, measured:
``notes/performance-log.md``, "Overlap slop".

Energy balance. With perfectly inelastic contacts, Coulomb friction and a converged solver the
change of kinetic energy over a step is at most the work of gravity: with v' = v + dt g + M^-1 H p,
Delta KE = W_g + sum p . u' - 1/2 sum m |v' - v|^2 (rotation included), where the contact power
p_n u_n = -p_n gap / dt is <= 0 unless the gap is negative (an overlap being pushed out) and
p_t u_t <= 0 by maximal dissipation. So
Delta KE - W_g > 0 (``StepRecord.energy_gain``) means spurious energy: overlaps relaxed by the gap
term, or an unconverged solver.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tiltpile.sim.detect import build_candidates, carry_impulses, interleave
from tiltpile.sim.jit import njit
from tiltpile.sim.solver import (C_B, C_IWN, C_IWT, C_MU, C_NX, C_NY, C_PN, IMPULSE, INTERLEAVED,
                                 N_CONTACT_COLUMNS, V_IM, V_S, V_X, V_Y, apply_impulses, nlgs)


@njit
def contact_geometry(pos, radius, vel, ci, cj, c, box_length, dt, mu, mu_wall, slop=0.0):
    """Fill c[:, 0:6] (normal, b = gap / dt, mu, 1/W_nn, 1/W_tt); return the largest overlap."""
    n = pos.shape[0]
    overlap = 0.0
    for a in range(ci.shape[0]):
        i = ci[a]
        j = cj[a]
        if j < n:
            dx = pos[i, 0] - pos[j, 0]
            dy = pos[i, 1] - pos[j, 1]
            dist = math.sqrt(dx * dx + dy * dy)
            nx = dx / dist
            ny = dy / dist
            gap = dist - radius[i] - radius[j]
            m = mu
        else:
            w = j - n
            if w == 0:
                nx, ny, gap = 0.0, 1.0, pos[i, 1] - radius[i]
            elif w == 1:
                nx, ny, gap = 1.0, 0.0, pos[i, 0] - radius[i]
            else:
                nx, ny, gap = -1.0, 0.0, box_length - pos[i, 0] - radius[i]
            m = mu_wall
        if -gap > overlap:
            overlap = -gap
        iw = 1.0 / (vel[i, V_IM] + vel[j, V_IM])
        c[a, C_NX] = nx
        c[a, C_NY] = ny
        # an overlap within the slop is left alone; a larger one is pushed back to the slop
        c[a, C_B] = gap / dt if gap >= 0.0 else min(0.0, gap + slop) / dt
        c[a, C_MU] = m
        c[a, C_IWN] = iw
        c[a, C_IWT] = iw / 3.0
    return overlap


class Bodies(NamedTuple):
    """The grains' arrays ``advance`` reads and updates in place (N grains)."""

    pos: np.ndarray     # (N, 2) centres [d]
    rot: np.ndarray     # (N,) rotation angles [rad]
    vel: np.ndarray     # (N + 3, 4) per body vx, vy, s = r omega, 1/m; rows N..N+2 the walls (solver)
    radius: np.ndarray  # (N,) [d]
    fixed: np.ndarray   # (N,) bool: grains glued to the floor (the rough bottom)
    ref: np.ndarray     # (N, 2) positions at the last build of the candidate list


class Contacts(NamedTuple):
    """The candidate contact list (C contacts), in the solver's layout (``solver`` docstring).

    ``advance`` updates these arrays in place, but a rebuild of the list replaces all of them, so
    it returns the list it ends with.
    """

    ci: np.ndarray      # (C,) int32 grain i
    cj: np.ndarray      # (C,) int32 body j: a grain, or N + w for wall w (floor, left, right)
    key: np.ndarray     # (C,) int64 pair key, ci * (N + 3) + cj
    c: np.ndarray       # (C, N_CONTACT_COLUMNS) per-contact columns C_NX .. C_PT
    status: np.ndarray  # (C,) int8 open, sticking or sliding
    perm: np.ndarray    # (C,) int64 scratch for the random and alternating sweep orders


class StepParams(NamedTuple):
    """The integrator's scalar parameters (``System.params``, typed as ``advance`` takes them)."""

    box_length: float   # [d]
    dt: float           # time step [sqrt(d / g)]
    alert: float        # alert distance of the candidate list [d]
    mu: float           # grain-grain friction coefficient
    mu_wall: float      # grain-wall friction coefficient
    tol: float          # NLGS tolerance on the relative impulse change
    max_iter: int       # NLGS sweep cap per step
    mode: int           # sweep order (``solver.SWEEPS``)
    relax: float        # over-relaxation factor omega (1: plain NLGS)
    slop: float         # overlap slop [d] (module docstring)
    gravity: float      # gravity magnitude [g]
    prune: bool         # pruned sweeps (``solver`` docstring)

    @classmethod
    def of(cls, params: dict) -> StepParams:
        """The parameters of a ``System.params`` dict, each converted to its field's type (so
        ``advance`` is compiled for one signature whatever numbers the dict holds)."""
        p = params
        return cls(float(p["box_length"]), float(p["dt"]), float(p["alert"]), float(p["mu"]),
                   float(p["mu_wall"]), float(p["tol"]), int(p["max_iter"]), int(p["mode"]),
                   float(p["relax"]), float(p["slop"]), float(p["gravity"]), bool(p["prune"]))


class StepLog(NamedTuple):
    """Per-step outputs of ``advance``: arrays of length n_steps, filled in place (``StepRecord``)."""

    iterations: np.ndarray  # int64 NLGS sweeps
    residual: np.ndarray    # final NLGS residual
    overlap: np.ndarray     # largest overlap at the start of the step [d]
    ke: np.ndarray          # kinetic energy of the mobile grains after the step [m g d]
    work: np.ndarray        # work of gravity over the step [m g d]
    missed: np.ndarray      # bool: a grain moved farther than alert / 2 since the last build
    updates: np.ndarray     # int64 local solves (contact updates)


@njit
def advance(bodies, contacts, rng_state, params, theta0, dtheta, n_steps, log):
    """Advance ``n_steps`` steps; gravity angle of step k is theta0 + (k + 1) dtheta [rad],
    its magnitude ``params.gravity`` (1 in every run; 0 in some validation tests).

    ``bodies`` (``Bodies``) and ``rng_state`` (the sweep-order generator, ``rng``) are updated in
    place, ``params`` is a ``StepParams``, ``log`` a ``StepLog`` of n_steps rows filled in place.
    Returns (contacts, n_rebuilds): the ``Contacts`` the steps end with (a rebuild replaces the
    arrays) and how many times the candidate list was rebuilt.
    """
    pos, rot, vel, radius = bodies.pos, bodies.rot, bodies.vel, bodies.radius
    fixed, ref = bodies.fixed, bodies.ref
    ci, cj, key, c = contacts.ci, contacts.cj, contacts.key, contacts.c
    status, perm = contacts.status, contacts.perm
    box_length = params.box_length
    dt = params.dt
    alert = params.alert
    mu = params.mu
    mu_wall = params.mu_wall
    tol = params.tol
    max_iter = params.max_iter
    mode = params.mode
    relax = params.relax
    slop = params.slop
    gravity = params.gravity
    prune = params.prune
    n = pos.shape[0]
    half = 0.5 * alert
    rebuilds = 0
    for k in range(n_steps):
        th = theta0 + (k + 1) * dtheta
        gx = gravity * math.sin(th)
        gy = -gravity * math.cos(th)
        reach = 0.0
        for i in range(n):
            if vel[i, V_IM] > 0.0:
                vel[i, V_X] += dt * gx
                vel[i, V_Y] += dt * gy
            ddx = pos[i, 0] - ref[i, 0]
            ddy = pos[i, 1] - ref[i, 1]
            r = math.sqrt(ddx * ddx + ddy * ddy) + dt * math.sqrt(vel[i, V_X] ** 2 + vel[i, V_Y] ** 2)
            if not r <= reach:  # also catches NaN
                reach = r
        if not reach < half:
            nci, ncj, nkey = build_candidates(pos, radius, fixed, box_length, alert)
            if mode == INTERLEAVED:
                order = interleave(nci, ncj, n + 3)
                nci, ncj, nkey = nci[order], ncj[order], nkey[order]
            nc = np.zeros((nci.shape[0], N_CONTACT_COLUMNS))
            carry_impulses(key, c[:, IMPULSE], nkey, nc[:, IMPULSE])
            ci, cj, key, c = nci, ncj, nkey, nc
            status = np.zeros(ci.shape[0], np.int8)
            perm = np.empty(ci.shape[0], np.int64)
            ref[:, :] = pos
            rebuilds += 1
        log.overlap[k] = contact_geometry(pos, radius, vel, ci, cj, c, box_length, dt, mu, mu_wall, slop)
        apply_impulses(ci, cj, c, vel)
        it, res, upd = nlgs(ci, cj, c, status, vel, tol, max_iter, mode, rng_state, perm, relax, prune)
        log.iterations[k] = it
        log.updates[k] = upd
        log.residual[k] = res
        ke = 0.0
        work = 0.0
        moved = 0.0
        for i in range(n):
            im = vel[i, V_IM]
            if im > 0.0:
                pos[i, 0] += dt * vel[i, V_X]
                pos[i, 1] += dt * vel[i, V_Y]
                rot[i] += dt * vel[i, V_S] / radius[i]
                ke += 0.5 * (vel[i, V_X] ** 2 + vel[i, V_Y] ** 2 + 0.5 * vel[i, V_S] ** 2) / im
                work += dt * (gx * vel[i, V_X] + gy * vel[i, V_Y]) / im
                ddx = pos[i, 0] - ref[i, 0]
                ddy = pos[i, 1] - ref[i, 1]
                moved = max(moved, ddx * ddx + ddy * ddy)
        log.ke[k] = ke
        log.work[k] = work
        log.missed[k] = moved > half * half
    return Contacts(ci, cj, key, c, status, perm), rebuilds


class StepRecord:
    """Per-step diagnostics of one ``System.advance`` call (arrays of length n_steps).

    ``ke0`` is the kinetic energy before the first step, ``work`` the work of gravity per step;
    ``energy_gain`` (property) is Delta KE - W_g per step, <= 0 up to solver error (module
    docstring).
    """

    __slots__ = ("iterations", "residual", "overlap", "ke", "work", "missed", "rebuilds", "ke0",
                 "updates")

    def __init__(self, n_steps: int):
        self.iterations = np.zeros(n_steps, np.int64)
        self.residual = np.zeros(n_steps)
        self.overlap = np.zeros(n_steps)
        self.ke = np.zeros(n_steps)
        self.work = np.zeros(n_steps)
        self.missed = np.zeros(n_steps, np.bool_)
        self.updates = np.zeros(n_steps, np.int64)  # local solves (contact updates) per step
        self.rebuilds = 0
        self.ke0 = 0.0

    @property
    def log(self) -> StepLog:
        """The per-step arrays as the ``StepLog`` that ``advance`` fills (the same arrays)."""
        return StepLog(self.iterations, self.residual, self.overlap, self.ke, self.work, self.missed,
                       self.updates)

    @property
    def energy_gain(self) -> np.ndarray:
        """Kinetic energy gained in each step beyond the work of gravity [m g d]."""
        before = np.concatenate([[self.ke0], self.ke[:-1]])
        return self.ke - before - self.work


class System:
    """The state of a pile and the parameters of its integrator; the thin layer over the kernels.

    State arrays (``ARRAYS``) are everything a bit-identical restart needs; ``scalars`` holds the
    run state the protocol keeps (a mapping of JSON values: ``protocol.RunState`` in a run).
    ``params`` (a dict, free to change between calls) holds the integrator's parameters:
    box_length, dt, alert, mu, mu_wall, tol, max_iter, sweep mode (``solver.SWEEPS``),
    over-relaxation factor ``relax`` (default 1 = plain NLGS, as ``solver.relax`` in the config),
    overlap ``slop``, gravity magnitude (1), ``prune`` (pruned sweeps in long steps,
    ``solver.prune``; off unless given). ``advance`` hands them to the kernel as a ``StepParams``,
    the arrays as ``Bodies`` and ``Contacts``.
    """

    ARRAYS = ("radius", "fixed", "pos", "rot", "vel", "ref", "ci", "cj", "key", "c", "status", "rng")

    def __init__(self, radius, fixed, pos, inv_mass, rng, *, box_length, dt, alert, mu, mu_wall,
                 tol, max_iter, mode, relax=1.0, slop=0.0, gravity=1.0, prune=False):
        from tiltpile.sim.solver import empty_contacts

        n = radius.shape[0]
        self.radius = np.ascontiguousarray(radius, dtype=np.float64)
        self.fixed = np.ascontiguousarray(fixed, dtype=np.bool_)
        self.pos = np.ascontiguousarray(pos, dtype=np.float64).copy()
        self.rot = np.zeros(n)
        self.vel = np.zeros((n + 3, 4))
        self.vel[:n, V_IM] = inv_mass
        self.ref = np.full((n, 2), np.inf)  # forces a build on the first step
        self.ci, self.cj, self.key, self.c, self.status = empty_contacts()
        self.perm = np.empty(0, np.int64)
        self.rng = rng
        self.params = dict(box_length=float(box_length), dt=float(dt), alert=float(alert), mu=float(mu),
                           mu_wall=float(mu_wall), tol=float(tol), max_iter=int(max_iter), mode=int(mode),
                           relax=float(relax), slop=float(slop), gravity=float(gravity),
                           prune=bool(prune))
        self.scalars: dict = {}

    @property
    def n(self) -> int:
        return self.radius.shape[0]

    def advance(self, n_steps: int, theta0_deg: float, dtheta_deg: float) -> StepRecord:
        """Run ``n_steps`` steps; step k (0-based) feels gravity at theta0 + (k + 1) dtheta."""
        self._order_contacts()
        rec = StepRecord(n_steps)
        rec.ke0 = self.kinetic_energy()
        bodies = Bodies(self.pos, self.rot, self.vel, self.radius, self.fixed, self.ref)
        contacts = Contacts(self.ci, self.cj, self.key, self.c, self.status, self.perm)
        contacts, rec.rebuilds = advance(bodies, contacts, self.rng, StepParams.of(self.params),
                                         math.radians(theta0_deg), math.radians(dtheta_deg), n_steps,
                                         rec.log)
        self.ci, self.cj, self.key, self.c, self.status, self.perm = contacts
        return rec

    def _order_contacts(self) -> None:
        """Store the contact list in the order the sweep mode expects: interleaved
        (``detect.interleave`` of the list sorted by key) for the interleaved sweep, sorted by key
        for the others. ``advance`` orders a rebuilt list itself; this catches a list stored under
        another mode (the mode changed in ``params``, or a state restored). Deterministic: an
        interleaved list comes out of the key-sorted one, so a list already in order is kept."""
        key = self.key
        is_sorted = key.size < 2 or bool(np.all(key[1:] > key[:-1]))
        if self.params["mode"] == INTERLEAVED:
            if not is_sorted:
                return
            order = interleave(self.ci, self.cj, self.n + 3)
        elif is_sorted:
            return
        else:
            order = np.argsort(key, kind="mergesort")
        for name in ("ci", "cj", "key", "c", "status"):
            setattr(self, name, np.ascontiguousarray(getattr(self, name)[order]))

    def kinetic_energy(self) -> float:
        """Kinetic energy of the mobile grains (translation and rotation, I = m r^2 / 2) [m g d]."""
        v = self.vel[: self.n]
        m = np.zeros(self.n)
        mob = v[:, V_IM] > 0
        m[mob] = 1.0 / v[mob, V_IM]
        return float(0.5 * np.sum(m * (v[:, V_X] ** 2 + v[:, V_Y] ** 2 + 0.5 * v[:, V_S] ** 2)))

    # -- views used by the protocol and the tests ---------------------------------------------
    @property
    def velocity(self) -> np.ndarray:
        return self.vel[: self.n, :2]

    @property
    def omega(self) -> np.ndarray:
        return self.vel[: self.n, V_S] / self.radius

    def contacts(self, active_only: bool = False):
        """Current contacts: (pair (C,2) int32 with wall ids < 0, force (C,2) = impulse / dt, status).

        Listed: contacts carrying a force and touching ones (gap <= 0) that carry none (status 0);
        ``active_only`` keeps those with f_n > 0.
        """
        from tiltpile.sim.detect import wall_ids

        p_n = self.c[:, C_PN]
        keep = p_n > 0 if active_only else (p_n > 0) | (self.c[:, C_B] <= 0)
        pair = np.column_stack([self.ci[keep], wall_ids(self.cj[keep], self.n)]).astype(np.int32)
        force = self.c[keep, IMPULSE] / self.params["dt"]
        return pair, force, self.status[keep].copy()

    def state(self) -> dict:
        """Copies of every state array plus the scalars (as a dict): enough for a bit-identical
        restart."""
        out = {k: getattr(self, k).copy() for k in self.ARRAYS}
        out["scalars"] = dict(self.scalars)
        return out

    def restore(self, state: dict) -> None:
        for k in self.ARRAYS:
            setattr(self, k, np.ascontiguousarray(state[k]).copy())
        self.perm = np.empty(self.ci.shape[0], np.int64)
        self.scalars = dict(state["scalars"])
