"""The settled piles every measurement starts from, deposited once and cached.

A bench pile has n mobile grains at the paper's depth: box length max(10, 120 d * n / 4000), so
~35 d deep as in the paper preset, deposited with the protocol of the chosen preset
(:func:`tiltpile.sim.protocol.deposited`). Its full simulator state is cached under
``data/bench/pile_n{n}_s{seed}_{config hash}.npz`` (written to a temporary name, then renamed), so
a later measurement of the same configuration starts from the same pile without depositing it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tiltpile import config as cfgmod
from tiltpile.sim import protocol

CACHE = Path("data/bench")


def bench_config(n: int, preset: str = "paper-fresh", config_file=None, overrides=()) -> cfgmod.Config:
    """The configuration of a bench pile of ``n`` grains: ``preset`` (+ ``config_file``,
    ``overrides``) with ``scene.n = n`` and ``scene.box_length = max(10, 120 n / 4000)`` [d].
    Raises ConfigError for n < 1 or an invalid override."""
    if n < 1:
        raise cfgmod.ConfigError(f"--n must be >= 1, got {n}")
    length = max(10.0, 120.0 * n / 4000)
    return cfgmod.load(preset, config_file, [*overrides, f"scene.n={n}", f"scene.box_length={length}"])


def settled_pile(cfg: cfgmod.Config, seed: int, progress: bool = True, cache: Path = CACHE):
    """A deposited pile (:class:`tiltpile.sim.step.System`) for ``cfg`` and ``seed``, at theta = 0
    and solved to ``cfg.solver.tol``: read from ``cache``, or deposited now (with a progress bar
    when ``progress``) and cached there."""
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


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.pile N [--preset paper-fresh] [--seed 0]``: deposit and cache a bench pile."""
    import argparse
    import sys

    ap = argparse.ArgumentParser(prog="python -m benchmarks.pile", description=main.__doc__)
    ap.add_argument("n", type=int, help="mobile grains")
    ap.add_argument("--preset", choices=cfgmod.PRESETS, default="paper-fresh",
                    help="base configuration of the pile (default: paper-fresh)")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    try:
        cfg = bench_config(a.n, a.preset)
    except cfgmod.ConfigError as e:
        print(f"{ap.prog}: error: {e}", file=sys.stderr)
        return 2
    s = settled_pile(cfg, a.seed)
    print(f"pile of {a.n} grains ({cfg.scene.box_length:g} d box, seed {a.seed}): "
          f"{s.ci.shape[0]} candidate contacts, cached in {CACHE}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
