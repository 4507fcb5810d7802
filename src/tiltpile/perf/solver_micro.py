"""Microbench of the NLGS sweep: ns per contact update at a fixed sweep count, all in one process.

Usage: python -m tiltpile.perf.solver_micro N SWEEPS REPEATS
"interleaved" sweeps the contact list in the order of detect.interleave, as a run with that sweep
stores it; the other orders sweep the list sorted by key. State: the bench pile of bench.settled_pile (cached, deposited if missing), tilted 20 steps. Also times the
same kernel compiled with fastmath={"contract"} (FMA) and fastmath=True, which the project does
not use (sim/jit.py).
"""
import sys
import time

import numba
import numpy as np

from tiltpile import bench
from tiltpile.sim import detect, solver

n, sweeps, reps = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
cfg = bench.bench_config(n)
s = bench.settled_pile(cfg, 0, progress=False)  # the cached pile of exactly this config
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
print("contacts", C)
res = {k: [] for k in variants}
cpu = {k: [] for k in variants}
for r in range(reps):
    for name, (mode, w, fn) in variants.items():
        ci, cj, c, stt = lists["interleaved" if mode == solver.INTERLEAVED else "key"]
        c = c.copy(); vel = s.vel.copy(); stt = stt.copy(); rng = s.rng.copy()
        t0 = time.perf_counter(); c0 = time.thread_time()
        fn(ci, cj, c, stt, vel, 0.0, sweeps, mode, rng, np.empty(C, np.int64), w)
        cpu[name].append(1e9 * (time.thread_time() - c0) / (sweeps * C))
        res[name].append(1e9 * (time.perf_counter() - t0) / (sweeps * C))
for name, v in res.items():
    print(f"{name:16s} median {np.median(v[1:]):6.2f} ns/update wall, {np.median(cpu[name][1:]):6.2f} cpu "
          f"(wall: {' '.join(f'{x:.1f}' for x in v)})")
