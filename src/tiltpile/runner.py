"""One run from configuration to run file: the glue between ``sim.protocol`` and ``store``.

``simulate(config, seed, out)`` writes ``out`` (via ``out.part``), resuming an interrupted
``.part`` of the same configuration from its last checkpoint, and returns a summary dict. Both the
``simulate`` command and the ensemble call it.

Health. Past a stop limit of ``config.health`` the protocol raises ``SimulationError``; the
``.part`` file stays (rerunning the same configuration resumes it and stops at the same place; a
changed configuration has another hash and starts afresh). A complete run is judged against the
warn limits over all its frames (``tiltpile.health.summarize``, resumed runs included): the summary
goes to the run file's ``/health`` attrs and to the returned dict (key ``health``; the ensemble
manifest records it per run), and any warnings are issued as one ``RuntimeWarning``.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

from tiltpile import health
from tiltpile.sim import protocol
from tiltpile.sim.jit import flags
from tiltpile.store import RunWriter


def simulate(config, seed: int, out: str | Path, *, progress: bool | str = True,
             resume: bool = True, position: int = 0, on_progress=None) -> dict:
    """Simulate one pile into ``out``; ``progress`` True for a terminal bar, "log" for lines;
    ``on_progress`` (optional) is called with every ``protocol.Progress`` event."""
    out = Path(out)
    t0 = time.perf_counter()
    resumed = RunWriter.resume(out, config.hash()) if resume else None
    if resumed is not None:
        writer, state = resumed
    else:
        sysm = protocol.make_system(config, seed)
        writer = RunWriter(out, config_json=config.to_json(), config_hash=config.hash(), seed=seed,
                           radius=sysm.radius, fixed=sysm.fixed, box_length=config.scene.box_length,
                           jit=flags())
        state = None
    start_frame = writer.n_frames
    bar = _Bar(config.protocol.theta_max_deg, seed, progress, position)
    try:
        for ev in protocol.run(config, seed, state):
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
            elif isinstance(ev, protocol.Progress):
                bar.update(ev)
                if on_progress is not None:
                    on_progress(ev)
        report = health.summarize(writer.frame_columns(health.COLUMNS), writer.deposition_attrs(),
                                  config, writer.n_mobile)
        writer.write_health(report)
        path = writer.finish()
    except protocol.SimulationError as e:
        writer.close()
        raise protocol.SimulationError(
            f"{e} The partial file {writer.part} is kept: rerunning the same configuration "
            "resumes it from its last checkpoint (and stops here again); a changed configuration "
            "has a new hash and starts afresh.") from e
    except BaseException:
        writer.close()
        raise
    finally:
        bar.close()
    message = health.warning_message(report, f"{path} (seed {seed})")
    if message is not None:
        warnings.warn(message, RuntimeWarning, stacklevel=2)
    return dict(path=str(path), seed=seed, seconds=time.perf_counter() - t0,
                resumed_from_frame=start_frame if resumed is not None else None,
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
