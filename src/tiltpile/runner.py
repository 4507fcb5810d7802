"""One run from configuration to run file: the glue between ``sim.protocol`` and ``store``.

``simulate(config, seed, out)`` writes ``out`` (via the frame log ``out.part``, from which the
writer builds ``out`` at the end), resuming an interrupted ``.part`` of the same configuration
from its last checkpoint, and returns a summary dict. Both the ``simulate`` command and the
ensemble call it (and ``tiltpile dem``). The engine is the configuration's (``Config.engine``):
Contact Dynamics (``sim.protocol.run``), or with a ``[dem]`` section the soft-sphere DEM
(``dem.protocol.run``, which needs LAMMPS: ``dem.lmp.DemUnavailable`` is raised before anything
is written); both yield the same events into the same layout.

One writer. The run file's writer lock (``store.writer_lock``, ``NAME.lock``) is held from before
anything is read or written until the end: a second process writing the same file is refused
with ``store.RunBusyError``, having changed nothing. An existing ``out`` is replaced only when the
new run is complete (the rename of the file built from ``out.part``); ``overwrite=False`` refuses to replace it
(``store.RunExistsError``). A ``.part`` that cannot be resumed (another configuration, no
checkpoint, damaged) is discarded with a ``RuntimeWarning`` saying why; the returned summary's
``discarded`` keeps the reason (None when nothing was discarded). A failed write (a full
disk, ...) raises ``store.RunWriteError`` with one line; the ``.part`` and its checkpoint stay for
the resume and no temporary file is left.

Health. Past a stop limit of ``config.health`` the protocol raises ``SimulationError``; the
``.part`` file stays if it has a checkpoint (rerunning the same configuration resumes it and
stops at the same place; a changed configuration has another hash and starts afresh), and is
removed if it has none (nothing to resume). A complete run is judged against the
warn limits over all its frames (``tiltpile.health.summarize``, resumed runs included): the summary
goes to the run file's ``/health`` attrs and to the returned dict (key ``health``; the ensemble
manifest records it per run), and any warnings are issued as one ``RuntimeWarning``.

Back from the file. ``system_from_frame(run, k)`` is the simulator ``System`` of a stored frame,
to continue a run from it (``tiltpile repose``) or to measure the solver on its state; the one
place where a run file's contacts become the kernels' (walls -1, -2, -3 -> N + k,
``sim.detect.kernel_ids``, the inverse of what ``System.contacts`` stores).
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np

from tiltpile import config as cfgmod
from tiltpile import health, store
from tiltpile.dem import lmp as dem_lmp
from tiltpile.dem import protocol as dem_protocol
from tiltpile.sim import protocol
from tiltpile.sim.detect import kernel_ids
from tiltpile.sim.jit import flags
from tiltpile.sim.solver import IMPULSE, N_CONTACT_COLUMNS
from tiltpile.sim.step import System
from tiltpile.store import Run, RunWriter


def simulate(config, seed: int, out: str | Path, *, progress: bool | str = True,
             resume: bool = True, position: int = 0, on_progress=None,
             overwrite: bool = True, pile=None) -> dict:
    """Simulate one pile into ``out``; ``progress`` True for a terminal bar, "log" for lines;
    ``on_progress`` (optional) is called with every ``protocol.Progress`` event; ``overwrite``
    False refuses an existing ``out`` (checked under the writer lock). ``pile`` (DEM only, a
    ``dem.protocol.Pile``): the starting pile, instead of depositing it (unused on resume)."""
    seed = cfgmod.check_seed(seed)
    out = Path(out)
    if config.dem is not None:
        dem_lmp.check_available()
    elif pile is not None:
        raise ValueError("a starting pile is for the DEM engine only (a configuration with [dem])")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise store.RunWriteError(f"cannot write {out}: {store._describe_os_error(e)}") from None
    with store.writer_lock(out):
        if out.exists() and not overwrite:
            raise store.RunExistsError(f"{out} exists (finished by another process?); nothing was changed")
        store.remove_stale_checkpoint(out)
        try:
            return _simulate(config, seed, out, progress, resume, position, on_progress, pile)
        except (OSError, RuntimeError) as e:
            if isinstance(e, (store.RunFileError, protocol.SimulationError)) or not store.is_write_failure(e):
                raise
            raise store.write_error(e, store.part_path(out)) from None


def _simulate(config, seed, out, progress, resume, position, on_progress, pile=None) -> dict:
    t0 = time.perf_counter()
    why: list[str] = []
    resumed = RunWriter.resume(out, config.hash(), why=why) if resume else None
    discarded = None
    if resumed is not None:
        writer, state = resumed
    else:
        part = store.part_path(out)
        discarded = part.exists()
        if pile is not None:
            radius, fixed = pile.radius, pile.fixed
        else:
            sysm = protocol.make_system(config, seed)
            radius, fixed = sysm.radius, sysm.fixed
        writer = RunWriter(out, config_json=config.to_json(), config_hash=config.hash(), seed=seed,
                           radius=radius, fixed=fixed, box_length=config.scene.box_length,
                           jit=flags())
        if discarded:
            reason = ("--no-resume (resume=False) was given" if not resume
                      else why[0] if why else "it cannot be resumed")
            discarded = reason
            warnings.warn(f"discarded {part}: {reason}; started afresh", RuntimeWarning, stacklevel=3)
        state = None
    start_frame = writer.n_frames
    bar = _Bar(config.protocol.theta_max_deg, seed, progress, position)
    try:
        events = (protocol.run(config, seed, state) if config.dem is None
                  else dem_protocol.run(config, seed, state, pile=pile))
        for ev in events:
            if isinstance(ev, protocol.Frame):
                writer.append(ev)
            elif isinstance(ev, protocol.Checkpoint):
                writer.checkpoint(ev.state)
            elif isinstance(ev, protocol.Deposited):
                writer.write_deposition(ev)
            elif isinstance(ev, protocol.Prepared):
                writer.write_preparation(ev.legs)
            elif isinstance(ev, protocol.Ended):
                writer.write_end(ev)
                ended = ev
            elif isinstance(ev, protocol.Progress):
                bar.update(ev)
                if on_progress is not None:
                    on_progress(ev)
        report = health.summarize(writer.frame_columns(health.COLUMNS), writer.deposition_attrs(),
                                  config, writer.n_mobile)
        writer.write_health(report)
        writer.write_timing(t0, start_frame if resumed is not None else None)
        path = writer.finish()
    except protocol.SimulationError as e:
        writer.close()
        if writer.ckpt.exists():
            what = (f"The partial file {writer.part} is kept: rerunning the same configuration "
                    "resumes it from its last checkpoint (and stops here again); a changed "
                    "configuration has a new hash and starts afresh.")
        else:
            writer.part.unlink(missing_ok=True)
            what = "Nothing was kept (the run stopped before its first checkpoint)."
        raise protocol.SimulationError(f"{e} {what}") from None
    except BaseException:
        writer.close()
        raise
    finally:
        bar.close()
    message = health.warning_message(report, f"{path} (seed {seed})")
    if message is not None:
        warnings.warn(message, RuntimeWarning, stacklevel=2)
    return dict(path=str(path), seed=seed, seconds=time.perf_counter() - t0,
                resumed_from_frame=start_frame if resumed is not None else None, discarded=discarded,
                end_reason=ended.reason, end_theta_deg=ended.theta_deg, steps=ended.steps,
                sweeps=ended.sweeps, capped_steps=ended.capped_steps,
                cap_hits=report["cap_hits"], missed=report["missed_steps"],
                max_overlap=report["max_overlap"], health=report)


def system_from_frame(run: Run | str | Path, k: int = -1) -> tuple[cfgmod.Config, System]:
    """(config, System) of a run as it was at its frame ``k`` (default the last); ``run`` an open
    ``store.Run`` or the path of a run file.

    The System is the run configuration's (``protocol.make_system``: same parameters, the seed's
    sweep-order generator) holding the file's grains (radius, fixed; mass = disk area) and the
    frame's positions, rotations, velocities and angular velocities. Its contact list is the
    frame's stored contacts with impulse = force * dt (the impulses of the frame's last step up
    to rounding; every contact carrying a force is stored), walls mapped back to the kernels'
    indices (``sim.detect.kernel_ids``), and its reference positions are unset so the first
    ``advance`` step rebuilds the candidate list and carries those impulses over
    (``detect.carry_impulses``). Measured on the smoke run (tests/test_repose.py),
    ``frame_every`` steps from frame k land on frame k + 1 within 1e-14 d in quiet frames and
    3e-7 d in the (capped) slide; impulses started from zero would need the first steps' sweeps
    to rebuild them (at the cap, the grains move by 1e-4 d).

    Its ``protocol.RunState``: phase "tilt", ``step`` the frame's global step, ``sweeps`` and
    ``capped_steps`` 0, and the iteration-cap counters of the run's health record
    (``steps_at_tol``, ``cap_hits``; 0 in a file without one). It is not a checkpoint: the
    contact list and the generator are not those the run had, so a continuation need not be
    bit-identical to the run going on. Raises IndexError for a frame the run does not have.
    """
    if not isinstance(run, Run):
        with store.open_run(run) as r:
            return system_from_frame(r, k)
    if not -run.n_frames <= k < run.n_frames:
        raise IndexError(f"frame {k} out of range: the run has {run.n_frames} frames")
    k = k % run.n_frames
    cfg = cfgmod.from_dict(run.config)
    sysm = protocol.make_system(cfg, run.seed)
    state = sysm.state()  # parameters and generator from the configuration; arrays replaced below
    radius = np.asarray(run.radius, dtype=np.float64)
    fixed = np.asarray(run.fixed, dtype=np.bool_)
    n = radius.size
    vel = np.zeros((n + 3, 4))
    vel[:n, :2] = run.velocity(k)
    vel[:n, 2] = run.omega(k) * radius  # the kernels carry the rim speed s = r omega
    vel[:n, 3] = np.where(fixed, 0.0, 1.0 / (np.pi * radius**2))  # as scene.make_scene
    pair, force, status = run.contacts(k)
    ci = pair[:, 0].astype(np.int32)
    cj = kernel_ids(pair[:, 1], n)
    key = ci.astype(np.int64) * (n + 3) + cj
    order = np.argsort(key, kind="mergesort")
    c = np.zeros((ci.size, N_CONTACT_COLUMNS))
    c[:, IMPULSE] = force[order] * cfg.solver.dt
    state.update(radius=radius, fixed=fixed, pos=np.asarray(run.position(k), dtype=np.float64),
                 rot=np.asarray(run.rotation(k), dtype=np.float64), vel=vel,
                 ref=np.full((n, 2), np.inf), ci=ci[order], cj=cj[order], key=key[order], c=c,
                 status=status[order].astype(np.int8))
    sysm.restore(state)
    h = run.health
    sysm.scalars = protocol.RunState(phase="tilt", step=int(run.step[k]),
                                     tol_steps=int(h.get("steps_at_tol", 0)),
                                     tol_cap_hits=int(h.get("cap_hits", 0)))
    return cfg, sysm


class _Bar:
    """tqdm over tilt angle (deposition shown as its step count) with mean NLGS sweeps;
    ``mode`` False disables it, "log" refreshes at most every 30 s (for log files)."""

    def __init__(self, theta_max_deg, seed, mode, position):
        # tqdm.auto in a notebook kernel without ipywidgets warns on import, even for a bar that
        # is off: the plain bar then
        if mode:
            from tqdm.auto import tqdm
        else:
            from tqdm import tqdm

        self.interval = 1.0 if mode != "log" else 30.0
        self.t = tqdm(total=round(theta_max_deg, 3), unit="deg", position=position,
                      desc=f"seed {seed} deposit", disable=not mode, leave=position == 0,
                      mininterval=self.interval,
                      bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.0f} deg "
                                 "[{elapsed}<{remaining}{postfix}]")
        self.seed = seed
        self.clock = time.monotonic
        self.shown = self.clock()

    def update(self, ev) -> None:
        if ev.phase == "deposit":
            self.t.set_description_str(f"seed {self.seed} deposit step {ev.step}", refresh=False)
        elif ev.phase == "pretilt":
            self.t.set_description_str(f"seed {self.seed} pretilt {ev.theta_deg:+.1f} deg",
                                       refresh=False)
        else:
            self.t.set_description_str(f"seed {self.seed} tilt", refresh=False)
        # the DEM has no sweeps (its events carry 0): its step count instead
        self.t.set_postfix_str(f"{ev.mean_iterations:.0f} sweeps/step" if ev.mean_iterations > 0
                               else f"step {ev.step}", refresh=False)
        if ev.phase == "tilt":
            self.t.update(ev.theta_deg - self.t.n)
        elif not self.t.disable and self.clock() - self.shown >= self.interval:
            # the deposit and the history do not move the tilt count, so tqdm would not redraw:
            # redraw their description (step, history angle) at the bar's own interval
            self.t.refresh()
            self.shown = self.clock()

    def close(self) -> None:
        self.t.close()
