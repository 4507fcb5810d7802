"""The numerical experiment: deposition under gravity, then quasi-static tilt.

``run(config, seed)`` is a generator of plain events; it never writes files. The caller (the
``simulate`` command, the ensemble) hands frames and checkpoints to ``tiltpile.store``.

1. Deposition. Grains start on a loose jittered lattice (``scene``) and fall into the horizontal
   box (theta = 0). Steps go in chunks of ``DEPOSITION_CHUNK``; deposition ends after the first
   chunk in which the kinetic energy per mobile grain has stayed below ``rest_ke`` for
   ``rest_steps`` consecutive steps; past ``max_deposition_steps`` the run stops with an error.
   Deposition solves to ``solver.deposition_tol`` (only its end state matters); the pile then
   takes ``rest_steps`` more steps at theta = 0 at ``solver.tol`` before frame 0.
2. Tilt. Gravity is rotated by ``tilt_per_step_deg`` every step from 0 to ``theta_max_deg``;
   frame 0 is the deposited pile at theta = 0 and a frame follows every ``frame_every`` steps
   (0.001 deg and 50 steps in the paper: 0.05 deg between frames).

Events: ``Deposited`` (summary), ``Prepared`` (the pretilt legs of the history, once they are
done; only with ``protocol.pretilt_deg``), ``Frame`` (arrays of one frame), ``Checkpoint`` (a full
state, every ``checkpoint_every`` frames and every ``DEPOSITION_CHUNK * 10`` deposition steps),
``Progress`` (for progress bars) and ``Ended`` (why and where the run stopped, and its cost).
A checkpoint holds the ``System``'s arrays and the ``RunState`` (the phase, step counts and
running totals). Resuming from it gives the same events after it, bit for bit, as the
uninterrupted run: every chunk boundary is a fixed multiple of steps.

Health (``config.HealthConfig``). Every chunk of steps is checked against the stop limits, and
``SimulationError`` names the limit, the measured value, the step and what to change:

* overlap: any step, deposition included, whose largest overlap exceeds ``overlap_stop``;
* energy: a tilt step whose kinetic energy grows by more than the work of gravity by over
  ``energy_stop`` per mobile grain (``StepRecord.energy_gain``);
* iteration cap: more than ``cap_hit_stop_fraction`` of the steps at ``solver.tol`` so far hit
  ``solver.max_iter``, judged once ``CAP_HIT_MIN_STEPS`` such steps have been made (the counters
  live in the checkpointed ``RunState``, so a resumed run judges the same totals). The steps
  counted are frame 0's settling and the tilt, those the health warning counts: the history's
  legs go past the repose angle by design (Deboeuf's cycles), so a pile flows there and caps
  the solver as in a slide, which says nothing about convergence (a mu = 0.8 pile cycled to
  +-16 deg capped 98% of its first 1400 such steps, and 24% of its tilt's).

Frames carry the per-step flags of their window (``max_overlap``, ``energy_gain``, ``cap_hits``,
``missed``); the warn limits are applied to them by ``runner.simulate``. Deposition has no energy
or cap-hit limit: it solves to the looser ``deposition_tol``, and only its end state matters. The
settling steps of frame 0 count towards the cap-hit fraction but are not judged for energy: they
re-solve the deposited pile from ``deposition_tol`` to ``solver.tol`` and release what the looser
solve left (default preset: up to 1.3e-6 m g d per grain, against <= 1.1e-7 in every tilt frame).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Iterator

import numpy as np

from tiltpile.sim import rng as srng
from tiltpile.sim.scene import make_scene
from tiltpile.sim.solver import SWEEPS
from tiltpile.sim.step import System

DEPOSITION_CHUNK = 200
OUT_OF_BOX = 2.0  # [d]: a grain this far outside the box means the integration has failed
CAP_HIT_MIN_STEPS = 500  # steps at solver.tol before the cap-hit fraction is judged


class SimulationError(RuntimeError):
    """The integration failed (NaN, grains escaping the box) or a protocol limit was passed."""


@dataclass
class Deposited:
    steps: int
    time: float
    ke_per_grain: float
    height: float  # highest grain top [d]
    max_overlap: float = 0.0  # largest overlap of any deposition step [d]
    missed: int = 0           # deposition steps where a grain outran the alert distance


@dataclass
class Frame:
    index: int
    step: int
    time: float
    theta_deg: float
    position: np.ndarray   # (N, 2)
    rotation: np.ndarray   # (N,)
    velocity: np.ndarray   # (N, 2)
    omega: np.ndarray      # (N,)
    iterations: int        # NLGS sweeps of the frame's step
    residual: float        # final NLGS residual of the frame's step
    pair: np.ndarray       # (C, 2) int32, wall ids -1 floor, -2 left, -3 right
    force: np.ndarray      # (C, 2) normal, tangential [m g]
    status: np.ndarray     # (C,) int8: 0 open, 1 sticking, 2 sliding
    ke: float              # kinetic energy of mobile grains at the frame [m g d]
    max_overlap: float     # largest overlap over the steps since the previous frame [d]
    max_iterations: int    # most sweeps of a step since the previous frame
    cap_hits: int          # steps since the previous frame that hit max_iter
    missed: int            # steps since the previous frame where a grain outran the alert distance
    energy_gain: float     # largest per-step KE gain beyond the work of gravity since the previous
                           # frame [m g d] (<= 0 up to solver error; sim/step.py)


@dataclass
class Prepared:
    legs: list             # one dict per pretilt leg: target_deg, tilt_steps, hold_steps, ke_per_grain


@dataclass
class Ended:
    reason: str            # "theta_max" (the ramp reached theta_max_deg) or "slide" (protocol.end_ke)
    theta_deg: float       # the angle of the last frame
    frames: int            # frames the run holds
    steps: int = 0         # time steps of the whole run (deposition and preparation included)
    sweeps: int = 0        # NLGS sweeps of all those steps: the run's cost in solver work
    capped_steps: int = 0  # steps that stopped at the iteration cap


@dataclass
class Checkpoint:
    state: dict            # System.state(): arrays, and scalars (a RunState as a dict)


@dataclass
class Progress:
    phase: str             # "deposit" or "tilt"
    step: int
    theta_deg: float
    mean_iterations: float


@dataclass
class RunState(Mapping):
    """Where a run stands and what it has counted: with the ``System``'s arrays, all that a
    checkpoint holds, so that a resumed run goes on bit for bit.

    ``System.scalars`` holds it during a run (``make_system``, ``run``). It reads as a mapping
    (read-only): ``dict(state)`` is the ``scalars`` of ``System.state()``, stored as JSON in the
    ``.ckpt`` file, and ``RunState.of`` reads such a mapping back (absent keys take the defaults
    below, unknown keys are ignored). The mapping holds the fields in the order declared here,
    each only once the run has reached the part that sets it: the preparation fields (``leg`` to
    ``deposition_height``) once deposition has ended, ``tol_steps`` and ``tol_cap_hits`` once a
    chunk at ``solver.tol`` has been judged, ``pretilt_chunks`` once it is not 0.
    """

    phase: str = "deposit"       # "deposit", "pretilt", "settle", "tilt", "done"; "repose" (repose.py)
    step: int = 0                # time steps made, every phase counted
    rest_count: int = 0          # consecutive steps at rest (``_count_rest``)
    tilt_step: int = 0           # steps of the tilt ramp made
    frame: int = 0               # the index of the next frame
    deposition_steps: int = 0    # deposition steps made
    rebuilds: int = 0            # rebuilds of the candidate contact list
    end_above: int = 0           # consecutive frames above ``protocol.end_ke``
    end_reason: str = "theta_max"  # why the run ends: "theta_max" or "slide" (``Ended``)
    sliding: bool = False        # the last frame was above ``solver.slide_cap_ke``
    sweeps: int = 0              # NLGS sweeps of every step so far
    capped_steps: int = 0        # steps that stopped at the iteration cap
    deposition_max_overlap: float = 0.0  # largest overlap of any deposition step [d]
    deposition_missed: int = 0   # deposition steps where a grain outran the alert distance
    # preparation (``protocol.pretilt_deg``): set when deposition ends
    leg: int = 0                 # the current pretilt leg
    leg_step: int = 0            # tilt steps of the current leg made
    leg_start: float = 0.0       # the angle the current leg starts from [deg]
    hold_steps: int = 0          # steps held at the current leg's angle
    preparation: list = field(default_factory=list)  # the finished legs (``Prepared.legs``)
    deposition_height: float = 0.0  # highest grain top at the end of deposition [d]
    # the iteration-cap counters of the health check (steps at solver.tol)
    tol_steps: int = 0
    tol_cap_hits: int = 0
    pretilt_chunks: int = 0      # chunks of the preparation that did not end a leg

    @classmethod
    def of(cls, scalars: Mapping) -> RunState:
        """The run state of a checkpoint's ``scalars`` (or a copy of a RunState)."""
        return cls(**{k: v for k, v in dict(scalars).items() if k in _RUN_STATE_FIELDS})

    def _stored(self, name: str) -> bool:
        """Whether the mapping holds the field ``name`` (class docstring)."""
        if name in _PREPARATION_FIELDS:
            return self.phase != "deposit"
        if name in ("tol_steps", "tol_cap_hits"):
            return self.tol_steps != 0
        if name == "pretilt_chunks":
            return self.pretilt_chunks != 0
        return True

    def __getitem__(self, key: str):
        if key in _RUN_STATE_FIELDS and self._stored(key):
            return getattr(self, key)
        raise KeyError(key)

    def __iter__(self):
        return (name for name in _RUN_STATE_FIELDS if self._stored(name))

    def __len__(self) -> int:
        return sum(1 for _ in self)


_RUN_STATE_FIELDS = tuple(f.name for f in fields(RunState))
_PREPARATION_FIELDS = ("leg", "leg_step", "leg_start", "hold_steps", "preparation",
                       "deposition_height")


def tilt_steps_total(protocol) -> int:
    return int(round(protocol.theta_max_deg / protocol.tilt_per_step_deg))


def n_frames(protocol) -> int:
    """Frames a run tilted to ``theta_max_deg`` holds: theta = 0 and one every ``frame_every``
    tilt steps (fewer when the end-of-run rule, ``protocol.end_ke``, ends it in a slide)."""
    return tilt_steps_total(protocol) // protocol.frame_every + 1


def make_system(config, seed: int) -> System:
    """A fresh pile (loose lattice) for ``config`` and ``seed``."""
    s, v = config.scene, config.solver
    gen = np.random.default_rng(np.random.SeedSequence([seed, 0x7117]))
    sc = make_scene(s.n, s.polydispersity, s.box_length, s.fill_spacing, gen)
    sysm = System(sc["radius"], sc["fixed"], sc["position"], sc["inv_mass"], srng.make_state(seed),
                  box_length=s.box_length, dt=v.dt, alert=v.alert, mu=s.mu, mu_wall=s.mu_wall,
                  tol=v.tol, max_iter=v.max_iter, mode=SWEEPS[v.sweep], relax=v.relax,
                  slop=v.overlap_slop, prune=v.prune)
    sysm.scalars = RunState()
    return sysm


def _check_sane(sysm: System, box_length: float) -> None:
    pos = sysm.pos
    if not np.all(np.isfinite(pos)) or not np.all(np.isfinite(sysm.vel)):
        raise SimulationError(f"non-finite positions or velocities at step {sysm.scalars.step}")
    out = (pos[:, 0] < -OUT_OF_BOX) | (pos[:, 0] > box_length + OUT_OF_BOX) | (pos[:, 1] < -OUT_OF_BOX)
    if out.any():
        raise SimulationError(f"{int(out.sum())} grains left the box at step {sysm.scalars.step} "
                              "(time step too large or solver not converged)")


def _frame(sysm: System, protocol, dt: float, rec) -> Frame:
    """The current state as a frame; ``rec`` is the StepRecord of the steps since the last one."""
    st = sysm.scalars
    pair, force, status = sysm.contacts()
    its = rec.iterations
    return Frame(index=st.frame, step=st.step, time=st.step * dt,
                 theta_deg=st.tilt_step * protocol.tilt_per_step_deg,
                 position=sysm.pos.copy(), rotation=sysm.rot.copy(), velocity=sysm.velocity.copy(),
                 omega=sysm.omega.copy(), iterations=int(its[-1]), residual=float(rec.residual[-1]),
                 pair=pair, force=force, status=status, ke=float(_ke(sysm)),
                 max_overlap=float(rec.overlap.max()), max_iterations=int(its.max()),
                 cap_hits=int((its >= sysm.params["max_iter"]).sum()), missed=int(rec.missed.sum()),
                 energy_gain=float(rec.energy_gain.max()))


def _ke(sysm: System) -> float:
    return sysm.kinetic_energy()


def _check_health(sysm: System, rec, health, n_mobile: int, phase: str, theta0_deg: float = 0.0,
                  dtheta_deg: float = 0.0) -> None:
    """Raise SimulationError past a stop limit of ``health`` (module docstring).

    Call after ``RunState.step`` has been advanced past the chunk ``rec``; ``phase`` is
    "deposit", "pretilt", "settle" or "tilt" (energy is judged in the history and the tilt, cap
    hits in the settling and the tilt: module docstring).
    """
    st = sysm.scalars
    k = rec.overlap.size
    first = st.step - k  # global step before the chunk

    def where(i: int) -> str:
        return (f"at step {first + i + 1} ({phase} phase, theta = "
                f"{theta0_deg + (i + 1) * dtheta_deg:.3f} deg)")

    i = int(np.argmax(rec.overlap))
    if rec.overlap[i] > health.overlap_stop:
        raise SimulationError(
            f"health.overlap_stop exceeded: grains overlap by {rec.overlap[i]:.3g} d {where(i)}, "
            f"limit {health.overlap_stop:g} d. Grains move too far per step for the contact "
            "model (missed contacts, linearised gaps): reduce solver.dt; if solver.max_iter is "
            "being hit, tighten solver.tol or raise solver.max_iter.")
    if phase == "deposit":
        return
    gain = rec.energy_gain / n_mobile
    i = int(np.argmax(gain))
    if phase in ("tilt", "pretilt") and gain[i] > health.energy_stop:
        raise SimulationError(
            f"health.energy_stop exceeded: the kinetic energy grew by {gain[i]:.3g} m g d per grain "
            f"more than gravity did work {where(i)}, limit {health.energy_stop:g}. Contacts "
            "created energy: the solver is not converged (tighten solver.tol, raise "
            "solver.max_iter) or overlaps are being pushed out (reduce solver.dt).")
    if phase == "pretilt":
        return
    caps = int((rec.iterations >= sysm.params["max_iter"]).sum())
    st.tol_steps += k
    st.tol_cap_hits += caps
    frac = st.tol_cap_hits / st.tol_steps
    if st.tol_steps >= CAP_HIT_MIN_STEPS and frac > health.cap_hit_stop_fraction:
        raise SimulationError(
            f"health.cap_hit_stop_fraction exceeded: {st.tol_cap_hits} of the {st.tol_steps} "
            f"steps at solver.tol up to step {st.step} ({phase} phase, theta = "
            f"{theta0_deg + k * dtheta_deg:.3f} deg) hit solver.max_iter = "
            f"{sysm.params['max_iter']} ({frac:.1%}, limit {health.cap_hit_stop_fraction:.1%}): the "
            "NLGS never converges, the grains behave as soft springs. Raise solver.max_iter (or "
            "loosen solver.tol).")


def run(config, seed: int, state: dict | None = None) -> Iterator[Deposited | Prepared | Frame | Checkpoint | Progress | Ended]:
    """Deposit and tilt one pile; resume from ``state`` (a ``Checkpoint.state``) if given."""
    sysm = make_system(config, seed)
    if state is not None:
        sysm.restore(state)
    st = sysm.scalars = RunState.of(sysm.scalars)
    proto, dt, health = config.protocol, config.solver.dt, config.health
    n_mobile = int((~sysm.fixed).sum())
    last_caps = None

    sysm.params["tol"] = config.solver.deposition_tol
    while st.phase == "deposit":
        if st.deposition_steps >= proto.max_deposition_steps:
            caps = "" if last_caps is None else (
                f"; {last_caps:.0%} of the last {DEPOSITION_CHUNK} steps hit solver.max_iter = "
                f"{config.solver.max_iter} (if many, raise it or loosen solver.deposition_tol)")
            raise SimulationError(
                f"deposition not at rest after {st.deposition_steps} steps (limit "
                f"protocol.max_deposition_steps = {proto.max_deposition_steps}, checked every "
                f"{DEPOSITION_CHUNK} steps) "
                f"(kinetic energy per grain {_ke(sysm) / n_mobile:.3g} > rest_ke {proto.rest_ke:g}"
                f"{caps}); raise protocol.max_deposition_steps or rest_ke")
        rec = _advance(sysm, DEPOSITION_CHUNK, 0.0, 0.0)
        st.step += DEPOSITION_CHUNK
        st.deposition_steps += DEPOSITION_CHUNK
        st.rebuilds += rec.rebuilds
        last_caps = float((rec.iterations >= config.solver.max_iter).mean())
        st.deposition_max_overlap = max(st.deposition_max_overlap, float(rec.overlap.max()))
        st.deposition_missed += int(rec.missed.sum())
        _check_health(sysm, rec, health, n_mobile, "deposit")
        _check_sane(sysm, config.scene.box_length)
        _count_rest(st, rec, n_mobile, proto.rest_ke)
        yield Progress("deposit", st.step, 0.0, float(rec.iterations.mean()))
        if st.rest_count >= proto.rest_steps:
            st.phase = "pretilt" if proto.pretilt_deg else "settle"
            st.leg, st.leg_step, st.leg_start, st.hold_steps, st.rest_count = 0, 0, 0.0, 0, 0
            st.preparation = []
            top = float(np.max(sysm.pos[:, 1] + sysm.radius))
            st.deposition_height = top
            yield Deposited(st.deposition_steps, st.step * dt, _ke(sysm) / n_mobile, top,
                            st.deposition_max_overlap, st.deposition_missed)
        elif (st.deposition_steps // DEPOSITION_CHUNK) % 10 == 0:
            yield Checkpoint(sysm.state())

    sysm.params["tol"] = config.solver.tol
    while st.phase == "pretilt":
        yield from _pretilt_chunk(sysm, config, n_mobile)

    if st.phase == "settle":
        # frame 0: the deposited (or prepared) pile brought to the tilt tolerance, rest_steps steps
        # at theta = 0
        rec = _advance(sysm, proto.rest_steps, 0.0, 0.0)
        st.step += proto.rest_steps
        _check_health(sysm, rec, health, n_mobile, "settle")
        _check_sane(sysm, config.scene.box_length)
        st.phase = "tilt"
        yield _frame(sysm, proto, dt, rec)
        st.frame = 1
        yield Checkpoint(sysm.state())

    total = tilt_steps_total(proto)
    span_frames = math.ceil(proto.end_span_deg / (proto.frame_every * proto.tilt_per_step_deg) - 1e-9)
    while st.phase == "tilt" and st.tilt_step < total:
        k = min(proto.frame_every, total - st.tilt_step)
        theta0 = st.tilt_step * proto.tilt_per_step_deg
        slide_cap = config.solver.max_iter_slide > 0 and st.sliding
        sysm.params["max_iter"] = config.solver.max_iter_slide if slide_cap else config.solver.max_iter
        rec = _advance(sysm, k, theta0, proto.tilt_per_step_deg)
        st.step += k
        st.tilt_step += k
        st.rebuilds += rec.rebuilds
        _check_health(sysm, rec, health, n_mobile, "tilt", theta0, proto.tilt_per_step_deg)
        _check_sane(sysm, config.scene.box_length)
        if k == proto.frame_every:
            frame = _frame(sysm, proto, dt, rec)
            yield frame
            st.frame += 1
            st.sliding = bool(frame.ke / n_mobile > config.solver.slide_cap_ke)
            if proto.end_ke > 0:
                st.end_above = st.end_above + 1 if frame.ke / n_mobile > proto.end_ke else 0
                if st.end_above >= span_frames:
                    st.phase, st.end_reason = "done", "slide"
        yield Progress("tilt", st.step, st.tilt_step * proto.tilt_per_step_deg,
                       float(rec.iterations.mean()))
        if st.tilt_step >= total:
            st.phase = "done"
        if st.phase == "done" or (st.frame - 1) % proto.checkpoint_every == 0:
            yield Checkpoint(sysm.state())
    yield Ended(st.end_reason, st.tilt_step // proto.frame_every * proto.frame_every
                * proto.tilt_per_step_deg, st.frame, st.step, st.sweeps, st.capped_steps)


def _count_rest(st: RunState, rec, n_mobile: int, rest_ke: float) -> None:
    """``st.rest_count``: consecutive steps, up to the last of ``rec``, with kinetic energy
    per mobile grain below ``rest_ke`` (how deposition and every pretilt leg end)."""
    for quiet in rec.ke / n_mobile < rest_ke:
        st.rest_count = st.rest_count + 1 if quiet else 0


def _advance(sysm: System, k: int, theta0_deg: float, dtheta_deg: float):
    """``sysm.advance``, counting the sweeps and capped steps of the run in its ``RunState``."""
    rec = sysm.advance(k, theta0_deg, dtheta_deg)
    st = sysm.scalars
    st.sweeps += int(rec.iterations.sum())
    st.capped_steps += int((rec.iterations >= sysm.params["max_iter"]).sum())
    return rec


def _pretilt_chunk(sysm: System, config, n_mobile: int):
    """One chunk of the preparation history (``protocol.pretilt_deg``): tilt towards the current
    leg's angle at ``pretilt_per_step_deg`` per step (the ramp's rate if 0), then hold there
    until at rest; events as ``run``'s."""
    st, proto = sysm.scalars, config.protocol
    legs = proto.pretilt_deg
    target, start = legs[st.leg], st.leg_start
    n_leg = int(round(abs(target - start) / proto.history_step_deg))
    if st.leg_step < n_leg:
        d = (target - start) / n_leg  # the last step lands on the target
        k = min(DEPOSITION_CHUNK, n_leg - st.leg_step)
        theta0 = start + st.leg_step * d
        rec = _advance(sysm, k, theta0, d)
        st.leg_step += k
        where = (theta0, d)
    else:
        k = DEPOSITION_CHUNK
        if st.hold_steps >= proto.max_deposition_steps:
            raise SimulationError(
                f"pretilt leg {st.leg} (to {target:g} deg) not at rest after holding "
                f"{st.hold_steps} steps (kinetic energy per grain {_ke(sysm) / n_mobile:.3g} > "
                f"rest_ke {proto.rest_ke:g}); raise protocol.max_deposition_steps or rest_ke")
        rec = _advance(sysm, k, target, 0.0)
        st.hold_steps += k
        _count_rest(st, rec, n_mobile, proto.rest_ke)
        where = (target, 0.0)
    st.step += k
    st.rebuilds += rec.rebuilds
    _check_health(sysm, rec, config.health, n_mobile, "pretilt", *where)
    _check_sane(sysm, config.scene.box_length)
    yield Progress("pretilt", st.step, where[0] + k * where[1], float(rec.iterations.mean()))
    if st.leg_step >= n_leg and st.rest_count >= proto.rest_steps:
        st.preparation = st.preparation + [dict(
            target_deg=float(target), tilt_steps=n_leg, hold_steps=int(st.hold_steps),
            ke_per_grain=_ke(sysm) / n_mobile)]
        st.leg, st.leg_start = st.leg + 1, float(target)
        st.leg_step, st.hold_steps, st.rest_count = 0, 0, 0
        if st.leg == len(legs):
            st.phase = "settle"
            yield Prepared(list(st.preparation))
            return
        yield Checkpoint(sysm.state())  # at the end of every leg but the last
        return
    st.pretilt_chunks += 1
    if st.pretilt_chunks % 10 == 0:
        yield Checkpoint(sysm.state())


def deposited(config, seed: int, on_progress=None) -> System:
    """The pile of ``config`` and ``seed`` as it is at frame 0: deposited and settled at theta = 0.

    Runs ``run`` up to its first tilt-phase checkpoint (frame 0) and stops; ``on_progress`` gets
    each ``Progress`` event on the way.
    """
    gen = run(config, seed)
    try:
        for ev in gen:
            if isinstance(ev, Progress) and on_progress is not None:
                on_progress(ev)
            if isinstance(ev, Checkpoint) and ev.state["scalars"]["phase"] == "tilt":
                sysm = make_system(config, seed)
                sysm.restore(ev.state)
                sysm.scalars = RunState.of(sysm.scalars)
                return sysm
    finally:
        gen.close()
    raise SimulationError("the protocol ended before deposition did")  # pragma: no cover

