"""One run from configuration to run file: the glue between ``sim.protocol`` and ``store``.

``simulate(config, seed, out)`` writes ``out`` (via ``out.part``), resuming an interrupted
``.part`` of the same configuration from its last checkpoint, and returns a summary dict. Both the
``simulate`` command and the ensemble call it.
"""

from __future__ import annotations

import time
from pathlib import Path

from tiltpile.sim import protocol
from tiltpile.sim.jit import flags
from tiltpile.store import RunWriter


def simulate(config, seed: int, out: str | Path, *, progress: bool | str = True,
             resume: bool = True, position: int = 0) -> dict:
    """Simulate one pile into ``out``; ``progress`` True for a terminal bar, "log" for lines."""
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
    warnings = {"cap_hits": 0, "missed": 0, "max_overlap": 0.0}
    try:
        for ev in protocol.run(config, seed, state):
            if isinstance(ev, protocol.Frame):
                writer.append(ev)
                warnings["cap_hits"] += ev.cap_hits
                warnings["missed"] += ev.missed
                warnings["max_overlap"] = max(warnings["max_overlap"], ev.max_overlap)
            elif isinstance(ev, protocol.Checkpoint):
                writer.checkpoint(ev.state)
            elif isinstance(ev, protocol.Deposited):
                writer.write_deposition(ev)
            elif isinstance(ev, protocol.Progress):
                bar.update(ev)
        path = writer.finish()
    except BaseException:
        writer.close()
        raise
    finally:
        bar.close()
    return dict(path=str(path), seed=seed, seconds=time.perf_counter() - t0,
                resumed_from_frame=start_frame if resumed is not None else None, **warnings)


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
        else:
            self.t.set_description(f"seed {self.seed} tilt", refresh=False)
            self.t.update(ev.theta_deg - self.t.n)
        self.t.set_postfix_str(f"{ev.mean_iterations:.0f} sweeps/step", refresh=False)

    def close(self) -> None:
        self.t.close()
