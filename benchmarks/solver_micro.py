"""Microbench of the NLGS sweep: ns per contact update at a fixed sweep count, all in one process.

Usage: python -m benchmarks.solver_micro N SWEEPS REPEATS

State: the bench pile of :func:`benchmarks.pile.settled_pile` (cached, deposited if
missing), tilted 20 steps. Each variant runs ``solver.nlgs`` for exactly SWEEPS sweeps (tol 0)
from copies of that state, REPEATS times, round-robin over the variants so that a slow spell of
the machine falls on all of them; reported: median wall and thread-CPU ns per contact update
over the repeats after the first. "interleaved" sweeps the contact list in the order of
``detect.interleave``, as a run with that sweep stores it; the other orders sweep the list sorted
by key. Also times the same kernel compiled with fastmath={"contract"} (FMA) and fastmath=True,
which the project does not use (``sim/jit.py``).
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def measure(n: int, sweeps: int, reps: int) -> dict:
    """{variant: (wall ns per update for each repeat, CPU ns per update for each repeat)} and
    the number of contacts, on the bench pile of ``n`` grains (module docstring)."""
    import numba

    from benchmarks.pile import bench_config, settled_pile
    from tiltpile.sim import detect, solver

    cfg = bench_config(n)
    s = settled_pile(cfg, 0, progress=False)  # the cached pile of exactly this config
    s.advance(20, 0.0, cfg.protocol.tilt_per_step_deg)
    C = s.ci.shape[0]
    fm = numba.njit(cache=False, nogil=True, fastmath={"contract"}, error_model="numpy")(solver.nlgs.py_func)
    fa = numba.njit(cache=False, nogil=True, fastmath=True, error_model="numpy")(solver.nlgs.py_func)
    srt = np.argsort(s.key, kind="mergesort")  # the pile stores its list in its own sweep's order
    o = srt[detect.interleave(s.ci[srt], s.cj[srt], s.vel.shape[0])]
    lists = {"key": (s.ci[srt], s.cj[srt], s.c[srt], s.status[srt]),
             "interleaved": (s.ci[o], s.cj[o], s.c[o], s.status[o])}
    variants = {
        "interleaved": (solver.INTERLEAVED, 1.0, solver.nlgs),
        "forward": (solver.FORWARD, 1.0, solver.nlgs),
        "alternating": (solver.ALTERNATING, 1.0, solver.nlgs),
        "random": (solver.RANDOM, 1.0, solver.nlgs),
        "forward-sor1.5": (solver.FORWARD, 1.5, solver.nlgs),
        "fwd-contract": (solver.FORWARD, 1.0, fm),
        "fwd-fastmath": (solver.FORWARD, 1.0, fa),
    }
    wall = {k: [] for k in variants}
    cpu = {k: [] for k in variants}
    for _ in range(reps):
        for name, (mode, w, fn) in variants.items():
            ci, cj, c, stt = lists["interleaved" if mode == solver.INTERLEAVED else "key"]
            c = c.copy()
            vel = s.vel.copy()
            stt = stt.copy()
            rng = s.rng.copy()
            t0 = time.perf_counter()
            c0 = time.thread_time()
            fn(ci, cj, c, stt, vel, 0.0, sweeps, mode, rng, np.empty(C, np.int64), w)
            cpu[name].append(1e9 * (time.thread_time() - c0) / (sweeps * C))
            wall[name].append(1e9 * (time.perf_counter() - t0) / (sweeps * C))
    return {"contacts": C, "variants": {k: (wall[k], cpu[k]) for k in variants}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.solver_micro",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("n", type=int, help="grains of the bench pile")
    ap.add_argument("sweeps", type=int, help="sweeps per timing")
    ap.add_argument("reps", type=int, help="repeats (the first is left out of the median)")
    a = ap.parse_args(argv)
    if a.n < 1 or a.sweeps < 1 or a.reps < 2:
        ap.error("N >= 1, SWEEPS >= 1 and REPEATS >= 2")
    res = measure(a.n, a.sweeps, a.reps)
    print("contacts", res["contacts"])
    for name, (w, c) in res["variants"].items():
        print(f"{name:16s} median {np.median(w[1:]):6.2f} ns/update wall, {np.median(c[1:]):6.2f} cpu "
              f"(wall: {' '.join(f'{x:.1f}' for x in w)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
