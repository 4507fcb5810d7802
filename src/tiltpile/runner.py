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
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile import health, store
from tiltpile.dem import lmp as dem_lmp
from tiltpile.dem import protocol as dem_protocol
from tiltpile.sim import protocol
from tiltpile.sim.jit import flags
from tiltpile.store import RunWriter


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


class _Bar:
    """tqdm over tilt angle (deposition shown as its step count) with mean NLGS sweeps;
    ``mode`` False disables it, "log" refreshes at most every 30 s (for log files)."""

    def __init__(self, theta_max_deg, seed, mode, position):
        from tqdm.auto import tqdm

        self.t = tqdm(total=round(theta_max_deg, 3), unit="deg", position=position,
                      desc=f"seed {seed} deposit", disable=not mode, leave=position == 0,
                      mininterval=1.0 if mode != "log" else 30.0,
                      bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.0f} deg "
                                 "[{elapsed}<{remaining}{postfix}]")
        self.seed = seed

    def update(self, ev) -> None:
        if ev.phase == "deposit":
            self.t.set_description(f"seed {self.seed} deposit step {ev.step}", refresh=False)
        elif ev.phase == "pretilt":
            self.t.set_description(f"seed {self.seed} pretilt {ev.theta_deg:+.1f} deg", refresh=False)
        else:
            self.t.set_description(f"seed {self.seed} tilt", refresh=False)
            self.t.update(ev.theta_deg - self.t.n)
        self.t.set_postfix_str(f"{ev.mean_iterations:.0f} sweeps/step", refresh=False)

    def close(self) -> None:
        self.t.close()
