"""What dask's housekeeping costs an ensemble: CPU beyond the runs, defaults against QUIET_DASK.

A LocalCluster of one worker process (as ``tiltpile ensemble`` makes them: one thread, the
library thread counts of ``ensemble.WORKER_ENV``) runs one busy task of ``--seconds`` of thread
CPU time; the CPU time of the client process (where the scheduler lives) and of the worker
process is read before and after (psutil). What the worker spends beyond the task, and the
client in that time, is the housekeeping: dask's statistical profiler (a stack sample of the
busy thread every 10 ms), event-loop ticks, system and memory monitors, work stealing::

    python -m tiltpile.bench.dask_overhead [--seconds 20] [--json]

Each setting (``default``: dask's configuration; ``quiet``: ``ensemble.QUIET_DASK``) gets a cluster
of its own. A paper run is one task of about two hours, so the overhead per second of task is
what it costs the ensemble.
"""

from __future__ import annotations

import argparse
import json
import time


def _busy(seconds: float) -> int:
    """Spin the worker thread for ``seconds`` of its own CPU time."""
    t, x = time.thread_time(), 0
    while time.thread_time() - t < seconds:
        for i in range(1000):
            x += i
    return x


def measure(setting: str, seconds: float) -> dict:
    """CPU seconds of the client and the worker process around one busy task of ``seconds``."""
    import dask
    import psutil
    from distributed import Client, LocalCluster

    from tiltpile.ensemble import QUIET_DASK, WORKER_ENV

    cfg = QUIET_DASK if setting == "quiet" else {}
    with dask.config.set(cfg), \
            LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                         dashboard_address=None, env=dict(WORKER_ENV)) as cluster, \
            Client(cluster) as client:
        time.sleep(2.0)                              # let the cluster settle after its start
        me = psutil.Process()
        (pid,) = client.run(lambda: __import__("os").getpid()).values()
        worker = psutil.Process(pid)

        def cpu(p):
            t = p.cpu_times()
            return t.user + t.system

        c0, w0, t0 = cpu(me), cpu(worker), time.perf_counter()
        client.submit(_busy, seconds, pure=False).result()
        c1, w1, wall = cpu(me), cpu(worker), time.perf_counter() - t0
    return {"setting": setting, "task_s": seconds, "wall_s": round(wall, 2),
            "client_cpu_s": round(c1 - c0, 3), "worker_extra_cpu_s": round(w1 - w0 - seconds, 3),
            "overhead_per_task_s": round((c1 - c0 + w1 - w0 - seconds) / seconds, 4)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tiltpile.bench.dask_overhead",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0, help="CPU seconds of the busy task")
    ap.add_argument("--json", action="store_true", help="one JSON line per setting")
    args = ap.parse_args(argv)
    if not args.seconds > 0:
        ap.error(f"--seconds must be > 0, got {args.seconds}")
    for setting in ("default", "quiet"):
        r = measure(setting, args.seconds)
        print(json.dumps(r) if args.json else
              f"{setting:8s} client {r['client_cpu_s']:.2f} s, worker beyond the task "
              f"{r['worker_extra_cpu_s']:.2f} s, in {r['wall_s']:.1f} s of wall time: "
              f"{r['overhead_per_task_s']:.1%} of the task's CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
