"""``tiltpile bench``: time the Contact Dynamics step on a settled pile of n grains.

The pile has the paper's depth (box length 120 d * n / 4000, so ~35 d deep) and is deposited
once with the protocol of the chosen preset; its state is cached under
``data/bench/pile_n{n}_{hash}.npz`` so later benchmarks skip the deposition. The timed part is
``steps`` steps of the quasi-static tilt from theta = 0 at the preset's tilt rate, after 20
untimed steps that bring the solver to the tilt tolerance.

Reported: ``contacts`` (candidate contacts swept by the NLGS), ``active_contacts`` (f_n > 0),
``mean_iterations`` (NLGS sweeps per step), ``ms_per_step`` (wall time of a whole step) and
``ns_per_contact_update`` (wall time / local solves made, i.e. contacts x sweeps less those a
pruned sweep leaves out: the cost of one local solve, everything else in the step amortised
into it). This is a measurement, not a test.

``tiltpile bench --chart DIR`` (``make bench``) measures the speed x accuracy chart instead
(tolerance and time-step sweep, Pareto plot, scaling in N): :mod:`tiltpile.perfchart`.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from tiltpile import config as cfgmod
from tiltpile.sim import protocol

CACHE = Path("data/bench")


def bench_config(n: int, preset: str = "paper", config_file=None, overrides=()) -> cfgmod.Config:
    if n < 1:
        raise cfgmod.ConfigError(f"--n must be >= 1, got {n}")
    length = max(10.0, 120.0 * n / 4000)
    return cfgmod.load(preset, config_file, [*overrides, f"scene.n={n}", f"scene.box_length={length}"])


def settled_pile(cfg: cfgmod.Config, seed: int, progress: bool = True, cache: Path = CACHE):
    """A deposited pile for ``cfg``: from the cache directory, or deposited now and cached."""
    cache = Path(cache)
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / f"pile_n{cfg.scene.n}_s{seed}_{cfg.hash()[:12]}.npz"
    if path.exists():
        sysm = protocol.make_system(cfg, seed)
        with np.load(path) as z:
            state = {k: z[k] for k in z.files if k != "scalars"}
            state["scalars"] = json.loads(str(z["scalars"]))
        sysm.restore(state)
        return sysm
    from tqdm.auto import tqdm

    with tqdm(desc=f"depositing {cfg.scene.n} grains (cached for next time)", unit="step",
              disable=not progress) as bar:
        sysm = protocol.deposited(cfg, seed, on_progress=lambda ev: bar.update(ev.step - bar.n))
    state = sysm.state()
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **{k: v for k, v in state.items() if k != "scalars"},
             scalars=json.dumps(state["scalars"]))
    tmp.replace(path)
    return sysm


def bench(n: int = 4000, steps: int = 200, preset: str = "paper", config_file=None, overrides=(),
          seed: int = 0, progress: bool = True) -> dict:
    if steps < 1:
        raise cfgmod.ConfigError(f"--steps must be >= 1, got {steps}")
    cfg = bench_config(n, preset, config_file, overrides)
    sysm = settled_pile(cfg, seed, progress)  # solves to cfg.solver.tol (make_system)
    dth = cfg.protocol.tilt_per_step_deg
    sysm.advance(20, 0.0, dth)
    t0 = time.perf_counter()
    rec = sysm.advance(steps, 20 * dth, dth)
    wall = time.perf_counter() - t0
    contacts = int(sysm.ci.shape[0])
    return dict(n=n, preset=preset, steps=steps, contacts=contacts,
                active_contacts=int((sysm.c[:, 6] > 0).sum()),
                mean_iterations=float(rec.iterations.mean()), ms_per_step=1e3 * wall / steps,
                ns_per_contact_update=1e9 * wall / max(1, int(rec.updates.sum())),
                tol=cfg.solver.tol, sweep=cfg.solver.sweep, dt=cfg.solver.dt)
