"""The numerical experiment of ``sim.protocol`` run by the DEM engine: the same pile, history and
ramp, the same events.

``run(config, seed, state=None, pile=None)`` yields ``sim.protocol``'s events -- ``Deposited``,
``Prepared``, ``Frame``, ``Checkpoint``, ``Progress``, ``Ended`` -- so that ``runner.simulate``
stores them in a run file of the same layout. ``config.dem`` (``config.DemConfig``) sets the
contact model (``pile.DemPile``); everything else is the Contact Dynamics configuration's.

1. The pile. Deposition is Contact Dynamics' own (``sim.protocol`` with the configuration
   without its history, ``config.without_history``): its frame 0 -- deposited and settled at
   theta = 0 -- is the DEM's starting pile, positions, velocities, spins and rotations (or the
   frame 0 of a run file of that configuration, ``Pile.of_frame``: the same arrays). Both engines
   start their histories and ramps from this pile.
2. Relax (DEM): the rigid pile becomes a soft one (the contacts compress by ~ m g / k_n per layer
   above): held at theta = 0 until at rest (below).
3. History (``protocol.pretilt_deg``): each leg tilts at ``pretilt_per_step_deg`` (or the
   ramp's rate) per Contact Dynamics step, i.e. per ``solver.dt`` of simulated time, then holds
   until at rest; ``Prepared`` at its end, as Contact Dynamics.
4. Settle: ``protocol.rest_steps`` Contact Dynamics steps of time at theta = 0; frame 0.
5. Ramp: ``tilt_per_step_deg`` per ``solver.dt`` to ``theta_max_deg`` (or the end-of-run rule
   ``protocol.end_ke``), a frame every ``frame_every`` Contact Dynamics steps of time, at the
   angles of the Contact Dynamics frames (theta_deg = tilt steps x tilt_per_step_deg).

Time. The DEM step is dt = solver.dt / q with q = ceil(solver.dt / dem.dt): q DEM steps span one
Contact Dynamics step, so every rate, leg and frame is a whole number of DEM steps. A frame's
``step`` counts DEM steps from the start of the DEM (relax included), its ``time`` is step x dt.
At rest: kinetic energy per mobile grain below ``protocol.rest_ke`` at every sample, taken every
``REST_SAMPLE`` Contact Dynamics steps of time, over ``protocol.rest_steps`` of them; a hold longer
than ``protocol.max_deposition_steps`` is a ``SimulationError``.

Frames. ``iterations``, ``max_iterations``, ``cap_hits`` and ``missed`` are 0 and ``residual`` 0.0
(there is no iterative solve; LAMMPS rebuilds its neighbour lists whenever a grain may have moved
half the skin, so no contact is missed); ``energy_gain`` is NaN (not measured); ``max_overlap``
is the largest overlap at the frame (not over the steps since the previous one). Contacts:
``DemPile.contacts``. ``health.overlap_stop`` stops a run whose frame overlaps more.

Dumps. Inside ``keeping_dumps(DIR)`` (``tiltpile dem --keep-dumps DIR``) every frame also writes
LAMMPS' own dumps of itself into DIR (``DemPile.contacts``: ``atoms.STEP.dump``,
``contacts.STEP.dump``), for ``tiltpile import`` and other tools; the run is the same, bit for
bit. A resumed run writes those of the frames it computes.

Checkpoints hold the LAMMPS binary restart (``lammps_restart``, bytes as uint8), the unwrapped
rotations and the ``DemState`` (``scalars``). Every stretch of steps is one LAMMPS ``run`` command
of a length fixed by the protocol, and a resumed run reads the restart where the uninterrupted
one wrote it, so the resumed run gives the same frames, bit for bit.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tiltpile.config import without_history
from tiltpile.dem.pile import DemPile
from tiltpile.sim import protocol as cd
from tiltpile.sim.protocol import (Checkpoint, Deposited, Ended, Frame, Prepared, Progress,
                                   SimulationError, n_frames, tilt_steps_total)

REST_SAMPLE = 10       # Contact Dynamics steps of time between kinetic-energy samples at rest
LEG_CHUNK = cd.DEPOSITION_CHUNK  # Contact Dynamics steps of a leg per LAMMPS run
CHECKPOINT_CHUNKS = 10  # legs and holds: a checkpoint every this many runs
_DUMPS: contextvars.ContextVar = contextvars.ContextVar("tiltpile_dem_dumps", default=None)


@contextlib.contextmanager
def keeping_dumps(directory):
    """Within this block, the DEM runs write LAMMPS dumps of every frame into ``directory``
    (module docstring, "Dumps"); it is made if missing."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    token = _DUMPS.set(directory)
    try:
        yield directory
    finally:
        _DUMPS.reset(token)


@dataclass
class Pile:
    """The starting pile: Contact Dynamics' frame 0 of ``config.without_history(config)``."""

    radius: np.ndarray     # (N,) [d]
    fixed: np.ndarray      # (N,) bool
    position: np.ndarray   # (N, 2) [d]
    velocity: np.ndarray   # (N, 2) [sqrt(g d)]
    omega: np.ndarray      # (N,) [sqrt(g/d)]
    rotation: np.ndarray   # (N,) [rad]
    deposited: Deposited   # the Contact Dynamics deposition's summary

    @classmethod
    def of_frame(cls, radius, fixed, frame: dict, deposition: dict) -> Pile:
        """From a run file's frame 0 (arrays position, velocity, omega, rotation) and its
        ``/deposition`` attrs."""
        d = deposition
        dep = Deposited(steps=int(d["steps"]), time=float(d["time"]),
                        ke_per_grain=float(d["ke_per_grain"]), height=float(d["height"]),
                        max_overlap=float(d.get("max_overlap", 0.0)), missed=int(d.get("missed", 0)))
        return cls(np.asarray(radius, np.float64), np.asarray(fixed, bool),
                   *(np.asarray(frame[k], np.float64) for k in ("position", "velocity", "omega", "rotation")),
                   deposited=dep)


def deposit(config, seed: int, on_progress=None) -> Pile:
    """The starting pile of ``config`` and ``seed`` from Contact Dynamics (module docstring);
    ``on_progress`` gets the deposition's ``Progress`` events."""
    gen = _deposit(config, seed)
    try:
        while True:
            ev = next(gen)
            if on_progress is not None:
                on_progress(ev)
    except StopIteration as stop:
        return stop.value


def _deposit(config, seed: int):
    """``deposit`` as a generator of the deposition's ``Progress`` events returning the pile."""
    fresh = without_history(config)
    gen = cd.run(fresh, seed)
    dep = None
    try:
        for ev in gen:
            if isinstance(ev, Progress):
                yield ev
            elif isinstance(ev, Deposited):
                dep = ev
            elif isinstance(ev, Frame):
                sysm = cd.make_system(fresh, seed)
                return Pile(sysm.radius.copy(), sysm.fixed.copy(), ev.position, ev.velocity,
                            ev.omega, ev.rotation, dep)
    finally:
        gen.close()
    raise SimulationError("the Contact Dynamics protocol ended before its frame 0")  # pragma: no cover


def pile_key(config) -> str:
    """What the starting pile depends on (the scene, the solver, the deposition's rest rule),
    as JSON: two configurations with the same key deposit the same pile for a seed."""
    proto = config.protocol
    return json.dumps({"scene": dataclasses.asdict(config.scene),
                       "solver": dataclasses.asdict(config.solver),
                       "rest": [proto.rest_ke, proto.rest_steps, proto.max_deposition_steps]},
                      sort_keys=True)


def substeps(config) -> tuple[int, float]:
    """(q, dt): DEM steps per Contact Dynamics step and the DEM time step (module docstring)."""
    q = max(1, math.ceil(config.solver.dt / config.dem.dt - 1e-9))
    return q, config.solver.dt / q


@dataclass
class DemState:
    """Where a DEM run stands (a checkpoint's ``scalars``, JSON)."""

    phase: str = "relax"     # "relax", "pretilt", "settle", "tilt", "done"
    rest_count: int = 0      # Contact Dynamics steps of time at rest so far (samples x REST_SAMPLE)
    hold_steps: int = 0      # Contact Dynamics steps of time held (relax or the current leg)
    relax_steps: int = 0     # ... of the relax phase, once it is over
    chunks: int = 0          # LAMMPS runs of the current leg or hold (checkpoint cadence)
    leg: int = 0
    leg_step: int = 0        # Contact Dynamics steps of the current leg tilted
    leg_start: float = 0.0   # [deg]
    preparation: list = field(default_factory=list)
    tilt_step: int = 0       # Contact Dynamics steps of the ramp made
    frame: int = 0           # index of the next frame
    end_above: int = 0
    end_reason: str = "theta_max"


def _make_pile(config, pile: Pile) -> DemPile:
    s = config.scene
    return DemPile(pile.radius, pile.fixed, pile.position, box_length=s.box_length, dem=config.dem,
                   mu=s.mu, mu_wall=s.mu_wall, dt=substeps(config)[1], velocity=pile.velocity,
                   omega=pile.omega, rotation=pile.rotation)


def _checkpoint(p: DemPile, st: DemState) -> Checkpoint:
    data = np.frombuffer(p.restart_bytes(), np.uint8).copy()
    return Checkpoint({"lammps_restart": data, "rotation": p.rotation, "radius": p.radius,
                       "fixed": p.fixed, "scalars": dataclasses.asdict(st)})


def run(config, seed: int, state: dict | None = None, pile: Pile | None = None):
    """The DEM run of ``config`` (with ``config.dem``) and ``seed``, resumed from ``state`` (a
    ``Checkpoint.state``) if given, else from ``pile`` (default: ``deposit(config, seed)``)."""
    if config.dem is None:
        raise ValueError("run needs a configuration with a [dem] section")
    proto, s = config.protocol, config.scene
    q, dt = substeps(config)
    if state is not None:
        st = DemState(**dict(state["scalars"]))
        p = DemPile.from_restart(np.asarray(state["lammps_restart"], np.uint8).tobytes(),
                                 state["rotation"], radius=state["radius"], fixed=state["fixed"],
                                 box_length=s.box_length, dem=config.dem, mu=s.mu,
                                 mu_wall=s.mu_wall, dt=dt)
    else:
        st = DemState()
        if pile is None:
            pile = yield from _deposit(config, seed)
        yield pile.deposited
        p = _make_pile(config, pile)
    try:
        yield from _run(config, p, st, q, dt)
    finally:
        p.close()


def _quiet(p: DemPile, n_mobile: int, rest_ke: float) -> bool:
    return p.kinetic_energy() / n_mobile < rest_ke


def _sane(p: DemPile, box_length: float) -> None:
    pos, vel, _ = p._arrays()
    if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
        raise SimulationError(f"non-finite positions or velocities at DEM step {p.step}")
    out = (pos[:, 0] < -cd.OUT_OF_BOX) | (pos[:, 0] > box_length + cd.OUT_OF_BOX) | (pos[:, 1] < -cd.OUT_OF_BOX)
    if out.any():
        raise SimulationError(f"{int(out.sum())} grains left the box at DEM step {p.step}")


def _advance(p: DemPile, n: int, theta0: float, dtheta: float, box_length: float) -> None:
    try:
        p.advance(n, theta0, dtheta)
    except RuntimeError as e:
        raise SimulationError(f"{e} (dem.dt too large for dem.kn?)") from None
    _sane(p, box_length)


def _hold(p, st, config, q, n_mobile, theta, what):
    """One sample's stretch of a hold at ``theta``: REST_SAMPLE steps of time, then the rest test."""
    proto = config.protocol
    if st.hold_steps >= proto.max_deposition_steps:
        raise SimulationError(
            f"{what} not at rest after holding {st.hold_steps} Contact Dynamics steps of time "
            f"(kinetic energy per grain {p.kinetic_energy() / n_mobile:.3g} > rest_ke "
            f"{proto.rest_ke:g}); raise protocol.max_deposition_steps or rest_ke")
    _advance(p, REST_SAMPLE * q, theta, 0.0, config.scene.box_length)
    st.hold_steps += REST_SAMPLE
    st.rest_count = st.rest_count + REST_SAMPLE if _quiet(p, n_mobile, proto.rest_ke) else 0
    return st.rest_count >= proto.rest_steps


def _run(config, p: DemPile, st: DemState, q: int, dt: float):
    proto, health, L = config.protocol, config.health, config.scene.box_length
    n_mobile = int((~p.fixed).sum())
    legs = proto.pretilt_deg
    dumps = _DUMPS.get()

    def frame() -> Frame:
        pair, force, status, overlap = p.contacts(config.dem.slide_eps, dumps=dumps)
        if overlap > health.overlap_stop:
            raise SimulationError(
                f"health.overlap_stop exceeded: grains overlap by {overlap:.3g} d at DEM step "
                f"{p.step} (theta = {st.tilt_step * proto.tilt_per_step_deg:.3f} deg), limit "
                f"{health.overlap_stop:g} d: raise dem.kn (and lower dem.dt)")
        pos, vel, om = p._arrays()
        return Frame(index=st.frame, step=p.step, time=p.step * dt,
                     theta_deg=st.tilt_step * proto.tilt_per_step_deg, position=pos,
                     rotation=p.rotation, velocity=vel, omega=om, iterations=0, residual=0.0,
                     pair=pair, force=force, status=status, ke=p.kinetic_energy(),
                     max_overlap=overlap, max_iterations=0, cap_hits=0, missed=0,
                     energy_gain=math.nan)

    while st.phase == "relax":
        done = _hold(p, st, config, q, n_mobile, 0.0, "the DEM pile (relaxing at theta = 0)")
        st.chunks += 1
        yield Progress("deposit", p.step, 0.0, 0.0)
        if done:
            st.phase = "pretilt" if legs else "settle"
            st.relax_steps, st.hold_steps, st.rest_count, st.chunks = st.hold_steps, 0, 0, 0
            yield _checkpoint(p, st)
        elif st.chunks % (CHECKPOINT_CHUNKS * LEG_CHUNK // REST_SAMPLE) == 0:
            yield _checkpoint(p, st)

    while st.phase == "pretilt":
        target, start = legs[st.leg], st.leg_start
        n_leg = int(round(abs(target - start) / proto.history_step_deg))
        if st.leg_step < n_leg:
            d = (target - start) / n_leg
            k = min(LEG_CHUNK, n_leg - st.leg_step)
            theta0 = start + st.leg_step * d
            _advance(p, k * q, theta0, d / q, L)
            st.leg_step += k
            yield Progress("pretilt", p.step, theta0 + k * d, 0.0)
            st.chunks += 1
            if st.chunks % CHECKPOINT_CHUNKS == 0:
                yield _checkpoint(p, st)
            continue
        done = _hold(p, st, config, q, n_mobile, target, f"pretilt leg {st.leg} (to {target:g} deg)")
        st.chunks += 1
        yield Progress("pretilt", p.step, target, 0.0)
        if done:
            st.preparation = st.preparation + [dict(
                target_deg=float(target), tilt_steps=n_leg, hold_steps=int(st.hold_steps),
                ke_per_grain=p.kinetic_energy() / n_mobile)]
            st.leg, st.leg_start = st.leg + 1, float(target)
            st.leg_step, st.hold_steps, st.rest_count, st.chunks = 0, 0, 0, 0
            if st.leg == len(legs):
                st.phase = "settle"
                yield Prepared(list(st.preparation))
            yield _checkpoint(p, st)
        elif st.chunks % (CHECKPOINT_CHUNKS * LEG_CHUNK // REST_SAMPLE) == 0:
            yield _checkpoint(p, st)

    if st.phase == "settle":
        _advance(p, proto.rest_steps * q, 0.0, 0.0, L)
        st.phase = "tilt"
        yield frame()
        st.frame = 1
        yield _checkpoint(p, st)

    total = tilt_steps_total(proto)
    span_frames = math.ceil(proto.end_span_deg / (proto.frame_every * proto.tilt_per_step_deg) - 1e-9)
    while st.phase == "tilt" and st.tilt_step < total:
        k = min(proto.frame_every, total - st.tilt_step)
        theta0 = st.tilt_step * proto.tilt_per_step_deg
        _advance(p, k * q, theta0, proto.tilt_per_step_deg / q, L)
        st.tilt_step += k
        if k == proto.frame_every:
            fr = frame()
            yield fr
            st.frame += 1
            if proto.end_ke > 0:
                st.end_above = st.end_above + 1 if fr.ke / n_mobile > proto.end_ke else 0
                if st.end_above >= span_frames:
                    st.phase, st.end_reason = "done", "slide"
        yield Progress("tilt", p.step, st.tilt_step * proto.tilt_per_step_deg, 0.0)
        if st.tilt_step >= total:
            st.phase = "done"
        if st.phase == "done" or (st.frame - 1) % proto.checkpoint_every == 0:
            yield _checkpoint(p, st)
    assert st.frame <= n_frames(proto)
    yield Ended(st.end_reason, st.tilt_step // proto.frame_every * proto.frame_every
                * proto.tilt_per_step_deg, st.frame, p.step, 0, 0)
