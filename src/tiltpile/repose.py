"""The repose angle of a finished run: tilt on into a large slide, then back until it stops.

Deboeuf et al. (PRE 72, 051305, 2005) give two angles for the piles the paper analysed: the
avalanche angle theta_a ~ 21 deg, where a large slide starts, and the repose angle
theta_r ~ 15 deg, where the flow stops when the pile is tilted back. ``repose(run_file)``
measures both on one of our piles by continuing it from a frame of its run file: the last
frame, unless the run's own frames already establish a slide (step 2's rule), then the frame that
establishes it. Otherwise a run that slid and came back to rest before it ended would be measured
on a second slide, at a much larger angle, and runs would turn back at different points of their
slides; ``from_last`` takes the last frame regardless.

1. Rebuild (``runner.system_from_frame``): the simulator ``System`` of the run's configuration,
   with the frame's grains, positions, rotations, velocities and angular velocities, its contact
   impulses warm-started from the frame's stored contact forces (impulse = force dt; contacts not
   stored carry no force and start at zero). The contact list is rebuilt at the first step and the
   sweep-order generator restarts from the seed, so the continuation need not be bit-identical to
   the run going on; measured on the smoke run, ``frame_every`` steps from a stored frame land on
   the next one within 1e-14 d in quiet frames and 3e-7 d in the (capped) slide
   (tests/test_repose.py). Impulses started from zero instead would have to be rebuilt by the
   NLGS: there the first steps hit the iteration cap and the grains move by 1e-4 d.
2. Forward: tilt on at the run's own rate (``protocol.tilt_per_step_deg`` per step), a *frame*
   (theta and kinetic energy per mobile grain, as in the run file) every ``protocol.frame_every``
   steps, until a slide is established: the kinetic energy per mobile grain of consecutive frames
   has stayed above ``ke_slide`` over ``slide_span_deg`` of tilt (the run's own frames up to
   the start frame count: a slide the run established turns back at once). The *slide angle* is
   the first frame of that span. No slide up to ``max_deg``: outcome "no slide", nothing more is
   done.
3. Reverse: from the frame where the slide is established, tilt back at the same rate, frames as
   before, until the kinetic energy per mobile grain has stayed below ``ke_stop`` over
   ``stop_span_deg``. The *stop angle* (our repose angle) is the first reverse frame of that
   quiet span. Still flowing at ``min_deg``: outcome "no stop".

Thresholds (kinetic energy per mobile grain, m g d; what our piles show, ``docs/method.md``):
quiet frames between events lie at 1e-10 to 1e-6, precursor rearrangements at 1e-5 to 5e-4,
large slides at 1e-3 to 1e-2. ``ke_slide`` = 1e-3 is the paper preset's ``protocol.end_ke``.
``ke_stop`` = 1e-5 is the lower edge of the precursors and a decade above the quiet frames: below
it for half a degree of tilt the slide is over and no rearrangement of precursor size is under
way, while the slow creep our piles keep between events (they rarely come below 1e-6) does not
hold the stop back.

Everything is deterministic: the same run file and parameters give the same numbers (only
``seconds`` differs). The solver work is that of the run's configuration (``solver.*``, the
``max_iter_slide`` rule included) and the health stop limits apply as in the run
(``sim.protocol``; the iteration-cap counters start from the run's totals), so a continuation that
breaks them raises ``SimulationError``.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from tiltpile import config as cfgmod
from tiltpile.sim import protocol
from tiltpile.analysis.structure import surface_tilt_deg
from tiltpile.paper_values import SLIDE_KE
from tiltpile.runner import system_from_frame
from tiltpile.store import RunFileError, open_run

KE_SLIDE = SLIDE_KE.value  # [m g d] per mobile grain: a large slide (paper preset's protocol.end_ke)
SLIDE_SPAN_DEG = 1.0  # [deg] of tilt the slide must last
KE_STOP = 1e-5        # [m g d] per mobile grain: the flow has stopped (module docstring)
STOP_SPAN_DEG = 0.5   # [deg] of tilt it must stay below
MAX_DEG = 35.0        # no slide by this angle: outcome "no slide"
MIN_DEG = 0.0         # still flowing at this angle: outcome "no stop"

OUTCOMES = ("stopped", "no slide", "no stop", "failed")


@dataclass
class Repose:
    """What ``repose`` measured on one run. Angles in deg (NaN where the outcome has none),
    kinetic energies per mobile grain in m g d.

    ``theta_deg``, ``ke``, ``direction`` (+1 forward, -1 reverse) and ``sweeps_per_frame``: one
    entry per frame of the continuation, in order (the run's own frames are not repeated).
    ``steps`` = forward_steps + reverse_steps time steps; ``sweeps`` their NLGS sweeps and
    ``capped_steps`` those that stopped at the iteration cap; ``max_overlap`` [d] and
    ``max_energy_gain`` (per mobile grain, m g d) the worst step of the continuation.
    """

    run: str
    seed: int
    outcome: str             # OUTCOMES
    start_frame: int         # the run's frame the continuation starts from
    start_deg: float         # its angle
    slide_deg: float         # first frame of the sustained slide
    reverse_deg: float       # angle at which the tilt was reversed
    stop_deg: float          # first reverse frame of the sustained quiet span: the repose angle
    surface_deg: float       # the free surface's slope to the horizontal once stopped
    forward_steps: int
    reverse_steps: int
    steps: int
    sweeps: int
    capped_steps: int
    max_overlap: float
    max_energy_gain: float
    seconds: float
    params: dict
    theta_deg: np.ndarray = field(repr=False)
    ke: np.ndarray = field(repr=False)
    direction: np.ndarray = field(repr=False)
    sweeps_per_frame: np.ndarray = field(repr=False)
    error: str = ""          # outcome "failed": the one-line reason (``repose_many``)

    def to_dict(self, trace: bool = True) -> dict:
        """Plain JSON-ready values (NaN as None); ``trace`` False leaves out the per-frame arrays."""
        out = {}
        for k, v in asdict(self).items():
            if isinstance(v, np.ndarray):
                if not trace:
                    continue
                v = v.tolist()
            out[k] = _json_value(v)
        return out


def _json_value(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [_json_value(x) for x in v]
    if isinstance(v, dict):
        return {k: _json_value(x) for k, x in v.items()}
    return v


def check_params(ke_slide: float, ke_stop: float, slide_span_deg: float, stop_span_deg: float,
                 max_deg: float, min_deg: float) -> None:
    """Raise ValueError (one line naming the parameter) unless the parameters make sense:
    thresholds finite and > 0 with ke_stop < ke_slide, spans finite and > 0, and
    0 <= min_deg < max_deg <= 90."""
    for name, v in (("ke_slide", ke_slide), ("ke_stop", ke_stop), ("slide_span_deg", slide_span_deg),
                    ("stop_span_deg", stop_span_deg)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    if ke_stop >= ke_slide:
        raise ValueError(f"ke_stop = {ke_stop:g} must be below ke_slide = {ke_slide:g}")
    if not (math.isfinite(max_deg) and math.isfinite(min_deg) and 0 <= min_deg < max_deg <= 90):
        raise ValueError(f"angles must satisfy 0 <= min_deg < max_deg <= 90, got min_deg = "
                         f"{min_deg!r}, max_deg = {max_deg!r}")


def span_frames(span_deg: float, frame_every: int, rate_deg: float) -> int:
    """Consecutive frames covering ``span_deg`` of tilt (as the protocol's end-of-run rule)."""
    return max(1, math.ceil(span_deg / (frame_every * rate_deg) - 1e-9))


def sustained_start(values, above: bool, threshold: float, n: int) -> int:
    """Index of the first entry of the first run of ``n`` consecutive entries above (``above``)
    or below ``threshold``; -1 if there is none."""
    count = 0
    for i, v in enumerate(values):
        hit = v > threshold if above else v < threshold
        count = count + 1 if hit else 0
        if count >= n:
            return i - n + 1
    return -1


def repose(run_file, *, ke_slide: float = KE_SLIDE, ke_stop: float = KE_STOP,
           slide_span_deg: float = SLIDE_SPAN_DEG, stop_span_deg: float = STOP_SPAN_DEG,
           max_deg: float = MAX_DEG, min_deg: float = MIN_DEG, from_last: bool = False,
           progress: bool = False, on_frame=None) -> Repose:
    """Slide and stop angles of the pile of ``run_file`` (module docstring).

    ``from_last``: continue from the run's last frame even when the run itself holds an
    established slide (by default the continuation then starts at the frame that established
    it, and reverses there). ``progress``: a tqdm bar over the frames of the continuation;
    ``on_frame(theta_deg, ke_per_grain, direction)`` is called after each frame. Raises
    ValueError for bad parameters (``check_params``), ``store.RunFileError`` for a file that is
    not a complete run file, and ``SimulationError`` past a health stop limit.
    """
    check_params(ke_slide, ke_stop, slide_span_deg, stop_span_deg, max_deg, min_deg)
    t0 = time.perf_counter()
    params = dict(ke_slide=float(ke_slide), ke_stop=float(ke_stop),
                  slide_span_deg=float(slide_span_deg), stop_span_deg=float(stop_span_deg),
                  max_deg=float(max_deg), min_deg=float(min_deg), from_last=bool(from_last))
    with open_run(run_file) as run:
        if run.n_frames < 1:
            raise RunFileError(f"{run.path}: the run has no frames")
        proto = cfgmod.from_dict(run.config).protocol
        rate, every = proto.tilt_per_step_deg, proto.frame_every
        n_slide = span_frames(slide_span_deg, every, rate)
        n_stop = span_frames(stop_span_deg, every, rate)
        n_mobile = int((~run.fixed).sum())
        run_ke = np.asarray(run.ke, dtype=float) / n_mobile
        run_theta = np.asarray(run.theta_deg, dtype=float)
        first = -1 if from_last else sustained_start(run_ke, True, ke_slide, n_slide)
        start_frame = run.n_frames - 1 if first < 0 else first + n_slide - 1
        cfg, sysm = system_from_frame(run, start_frame)
        sysm.scalars.phase = "repose"
        seed = run.seed
    run_ke, run_theta = run_ke[: start_frame + 1], run_theta[: start_frame + 1]
    run_theta = np.round(run_theta, 10)  # as the continuation's angles (``angle``)
    start = float(run_theta[-1])
    solver = cfg.solver
    st = sysm.scalars

    thetas, kes, dirs, sweeps = [], [], [], []
    worst = dict(overlap=0.0, gain=-math.inf)
    net = 0  # tilt steps forward minus steps back since the start frame

    def angle() -> float:  # rounded: 25.0 - 10 * 0.01 is 24.9, not 24.900000000000002
        return round(start + net * rate, 10)

    def frame(direction: int) -> float:
        nonlocal net
        theta0 = angle()
        sliding = solver.max_iter_slide > 0 and (kes[-1] if kes else run_ke[-1]) > solver.slide_cap_ke
        sysm.params["max_iter"] = solver.max_iter_slide if sliding else solver.max_iter
        rec = protocol._advance(sysm, every, theta0, direction * rate)
        net += direction * every
        st.step += every
        protocol._check_health(sysm, rec, cfg.health, n_mobile, "tilt", theta0, direction * rate)
        protocol._check_sane(sysm, cfg.scene.box_length)
        worst["overlap"] = max(worst["overlap"], float(rec.overlap.max()))
        worst["gain"] = max(worst["gain"], float(rec.energy_gain.max()) / n_mobile)
        theta, ke = angle(), sysm.kinetic_energy() / n_mobile
        thetas.append(theta)
        kes.append(ke)
        dirs.append(direction)
        sweeps.append(int(rec.iterations.sum()))
        bar.update(theta, ke, direction)
        if on_frame is not None:
            on_frame(theta, ke, direction)
        return ke

    bar = _Bar(Path(run_file).name, progress)
    slide = reverse = stop = surface = math.nan
    try:
        # forward: the run's trailing frames above ke_slide count towards the span
        above = 0
        while above < run_ke.size and run_ke[run_ke.size - 1 - above] > ke_slide:
            above += 1
        first_above = float(run_theta[run_ke.size - above]) if above else math.nan
        while above < n_slide and angle() < max_deg - 1e-9:
            if frame(+1) > ke_slide:
                above += 1
                if above == 1:
                    first_above = thetas[-1]
            else:
                above = 0
        forward_steps = net
        if above >= n_slide:
            slide, reverse = float(first_above), angle()
            below, first_below = 0, math.nan
            while below < n_stop and angle() > min_deg + 1e-9:
                if frame(-1) < ke_stop:
                    below += 1
                    if below == 1:
                        first_below = thetas[-1]
                else:
                    below = 0
            if below >= n_stop:
                stop = float(first_below)
                surface = angle() - surface_tilt_deg(sysm.pos, sysm.radius, sysm.fixed,
                                                     cfg.scene.box_length)
            outcome = "stopped" if below >= n_stop else "no stop"
        else:
            outcome = "no slide"
    finally:
        bar.close()
    reverse_steps = forward_steps - net
    return Repose(run=str(run_file), seed=int(seed), outcome=outcome, start_frame=int(start_frame),
                  start_deg=start,
                  slide_deg=slide, reverse_deg=reverse, stop_deg=stop, surface_deg=surface,
                  forward_steps=int(forward_steps), reverse_steps=int(reverse_steps),
                  steps=int(forward_steps + reverse_steps), sweeps=int(st.sweeps),
                  capped_steps=int(st.capped_steps), max_overlap=worst["overlap"],
                  max_energy_gain=worst["gain"] if thetas else math.nan,
                  seconds=time.perf_counter() - t0, params=params,
                  theta_deg=np.array(thetas, dtype=float), ke=np.array(kes, dtype=float),
                  direction=np.array(dirs, dtype=np.int8),
                  sweeps_per_frame=np.array(sweeps, dtype=np.int64))


class _Bar:
    """tqdm over the frames of the continuation, showing the phase, theta and KE per grain."""

    def __init__(self, name: str, mode: bool):
        from tqdm.auto import tqdm

        self.name = name
        self.t = tqdm(unit="frame", desc=f"{name} forward", disable=not mode, leave=False,
                      mininterval=1.0, bar_format="{desc}: {n} frames [{elapsed}{postfix}]")

    def update(self, theta: float, ke: float, direction: int) -> None:
        self.t.set_description_str(f"{self.name} {'forward' if direction > 0 else 'reverse'}",
                                   refresh=False)
        self.t.set_postfix_str(f"{theta:.2f} deg, KE {ke:.1e} per grain", refresh=False)
        self.t.update(1)

    def close(self) -> None:
        self.t.close()


# ----------------------------------------------------------------------------------------------
# many runs


def _failed(path, seed: int, params: dict, error: str) -> Repose:
    empty = np.zeros(0)
    nan = math.nan
    return Repose(run=str(path), seed=seed, outcome="failed", start_frame=-1, start_deg=nan,
                  slide_deg=nan,
                  reverse_deg=nan, stop_deg=nan, surface_deg=nan, forward_steps=0, reverse_steps=0, steps=0,
                  sweeps=0, capped_steps=0, max_overlap=nan, max_energy_gain=nan, seconds=0.0,
                  params=params, theta_deg=empty, ke=empty, direction=empty.astype(np.int8),
                  sweeps_per_frame=empty.astype(np.int64), error=error)


def _repose_one(path: str, params: dict, progress: bool = False) -> Repose:
    """``repose`` of one file; a health stop (or a file damaged past its layout) is recorded as
    outcome "failed" with its one-line reason, so one bad run does not lose the others."""
    try:
        return repose(path, progress=progress, **params)
    except (protocol.SimulationError, RunFileError) as e:
        full = dict(ke_slide=KE_SLIDE, ke_stop=KE_STOP, slide_span_deg=SLIDE_SPAN_DEG,
                    stop_span_deg=STOP_SPAN_DEG, max_deg=MAX_DEG, min_deg=MIN_DEG, from_last=False)
        full.update(params)
        full = {k: v if isinstance(v, bool) else float(v) for k, v in full.items()}
        return _failed(path, -1, full, " ".join(str(e).split()))


def repose_many(files, *, workers: int = 1, progress: bool = False, on_result=None,
                **params) -> list[Repose]:
    """``repose`` of each run file (``params`` as its keyword arguments), in the order given.

    ``workers`` > 1: that many processes (spawned; each file in one of them). ``progress``: with
    one worker a bar per run, with more a bar over the runs. ``on_result(Repose)`` is called as
    each run finishes (in completion order). A run stopped by a health limit comes back with
    outcome "failed" and its reason in ``error``; the others are unaffected.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    check_params(**{**dict(ke_slide=KE_SLIDE, ke_stop=KE_STOP, slide_span_deg=SLIDE_SPAN_DEG,
                           stop_span_deg=STOP_SPAN_DEG, max_deg=MAX_DEG, min_deg=MIN_DEG),
                    **{k: v for k, v in params.items() if k != "from_last"}})
    files = [str(f) for f in files]
    results: dict[str, Repose] = {}
    nw = min(workers, len(files))
    if nw <= 1:
        for f in files:
            results[f] = _repose_one(f, params, progress)
            if on_result is not None:
                on_result(results[f])
        return [results[f] for f in files]
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from multiprocessing import get_context

    from tqdm.auto import tqdm

    bar = tqdm(total=len(files), desc="repose", unit="run", disable=not progress)
    try:
        with ProcessPoolExecutor(max_workers=nw, mp_context=get_context("spawn")) as ex:
            futs = {ex.submit(_repose_one, f, params): f for f in files}
            for fut in as_completed(futs):
                r = fut.result()
                results[futs[fut]] = r
                bar.update(1)
                if on_result is not None:
                    on_result(r)
    finally:
        bar.close()
    return [results[f] for f in files]


def summarize(results) -> dict:
    """Ensemble summary: outcome counts, and the mean with a bootstrap 95% interval over runs
    (``analysis.stats.bootstrap_ci``; runs without the angle left out) of the stop angle, the
    slide angle and their difference; total steps, sweeps and seconds. NaN as None."""
    from tiltpile.analysis.stats import bootstrap_ci

    results = list(results)
    stop = np.array([r.stop_deg for r in results], dtype=float)
    slide = np.array([r.slide_deg for r in results], dtype=float)
    out = {"runs": len(results), "outcomes": {o: sum(r.outcome == o for r in results) for o in OUTCOMES}}
    surface = np.array([r.surface_deg for r in results], dtype=float)
    for name, values in (("stop_deg", stop), ("slide_deg", slide), ("slide_minus_stop_deg", slide - stop),
                         ("surface_deg", surface)):
        ci = bootstrap_ci(values)
        out[name] = {k: ci[k] for k in ("estimate", "low", "high", "n", "confidence", "method")}
    out.update(steps=int(sum(r.steps for r in results)), sweeps=int(sum(r.sweeps for r in results)),
               seconds=float(sum(r.seconds for r in results)))
    return _json_value(out)


def write_json(out, document: dict) -> None:
    """Write ``document`` to ``out`` via a temporary file synced and renamed over it when
    complete (:func:`tiltpile.outputs.replaced_whole`)."""
    import json

    from tiltpile.outputs import replaced_whole

    with replaced_whole(out) as tmp, open(tmp, "w") as fh:
        json.dump(document, fh, indent=1, allow_nan=False)
        fh.write("\n")
