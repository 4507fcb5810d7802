"""Ensembles of runs on dask.distributed: resumable, reproducible, one machine or a cluster.

``run_ensemble(config, seeds, out_dir)`` runs one pile per seed into ``out_dir/run_{seed:04d}.h5``
(``runner.simulate``'s format) and keeps a manifest ``out_dir/ensemble.json``; its command line,
``tiltpile ensemble``, lives in :mod:`tiltpile.cli.ensemble`::

    tiltpile ensemble --preset P [--config F] [--set k=v ...] --runs M [--first-seed S] --out DIR
                      [--scheduler ADDRESS] [--workers W]

Engine. One dask task per seed calls ``runner.simulate(config, seed, DIR/run_SSSS.h5,
progress=False, resume=True)``. Without ``scheduler`` a ``LocalCluster`` is started (worker
processes, one thread each, ``workers`` of them, default one per core but no more than there are
runs); with ``scheduler="tcp://host:port"`` the same tasks go to an existing cluster, whose workers
must see ``DIR`` at the same path (a shared file system) and import the same ``tiltpile``.

Manifest (``ensemble.json``, rewritten atomically -- temporary file, then ``os.replace`` -- by the
client as runs start and finish): ``config`` (the validated configuration), ``config_hash``,
``seeds``, ``runs`` keyed by seed (``file``, ``status`` pending | running | done | failed,
``error`` and ``traceback`` of a failure, ``attempts``, ``started``/``finished`` (UTC, ISO 8601),
``seconds``, ``worker``, ``resumed_from_frame``, ``discarded`` (why a ``.part`` found was not
resumed), ``cap_hits``/``missed``/``max_overlap`` and the
run's ``health`` summary with its ``warnings`` (``tiltpile.health``), ``numba_cache_misses``),
``tiltpile_version`` and library ``versions``, and one entry per invocation in ``invocations``.

Idempotent and resumable. A seed whose complete run file exists and passes ``store.verify``
(layout and every checksum; the manifest records the size and mtime of a file found sound as
``verified``, and an unchanged file is not read again: a flipped bit on disk that leaves them is
still caught by the checksums when the file is read) is skipped; one that fails is moved aside to ``run_SSSS.h5.damaged``
(saying so on stderr) and run again. Anything else is
(re)submitted: an interrupted run resumes from its checkpoint (``run_SSSS.h5.ckpt`` beside the
``.part`` file) and ends
bit-identical to an uninterrupted run (``runner``/``store``); a failed run is retried. A failure
is recorded and the other runs go on; ``run_ensemble`` returns the manifest and the command exits
with status 1 if any run failed. An existing ``DIR`` whose manifest (or any ``run_*.h5``) belongs to
another configuration is refused with ``ConfigError`` before anything is written, as is bad input
(no seeds, a negative seed or one past 2**63 - 1, ``workers < 1``). Two invocations on one ``DIR`` at once are refused too
(``DIR/.ensemble.lock``, an advisory ``flock`` released when the process dies:
:func:`tiltpile.outputs.output_lock`; ``OutputBusy``, one line naming the holder).

numba in workers. The kernels are compiled with ``cache=True`` (``sim/jit.py``) and without
``parallel``: one task uses one core. Before submitting, the client compiles them once by stepping a
two-grain system (``warm_numba_cache``), which writes the machine code to numba's cache:
``$NUMBA_CACHE_DIR`` if set (the Makefile exports ``.venv/numba-cache``), otherwise
``src/tiltpile/sim/__pycache__``. Workers load it from there instead of compiling (each run records
``numba_cache_misses``, 0 when nothing was compiled), and a worker process keeps the loaded code for
all its later tasks. LocalCluster workers get ``NUMBA_NUM_THREADS``, ``OMP_NUM_THREADS``,
``MKL_NUM_THREADS`` and ``OPENBLAS_NUM_THREADS`` = 1 and the client's ``NUMBA_CACHE_DIR``; workers
of an external cluster must be started with the same environment. A worker on a CPU unlike the
client's (the cache is keyed by CPU) compiles once per worker process, never once per task.

SLURM with dask-jobqueue (the ``cluster`` extra: ``pip install .[cluster]``)::

    from dask_jobqueue import SLURMCluster
    from tiltpile import config, ensemble
    cluster = SLURMCluster(cores=1, processes=1, memory="2GB", walltime="24:00:00",
                           job_script_prologue=["export NUMBA_NUM_THREADS=1",
                                                "export NUMBA_CACHE_DIR=$HOME/tiltpile/.venv/numba-cache"])
    cluster.scale(jobs=50)
    ensemble.run_ensemble(config.load("paper"), range(50), "data/paper", scheduler=cluster)

or start ``dask scheduler`` and ``dask worker`` jobs yourself and pass ``--scheduler tcp://host:port``.
If the client is killed, tasks already running on an external cluster finish on their own; a run
whose ``.part`` file is still held by such a task fails with a locked-file error and is retried by
the next invocation.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import operator
import os
import sys
import threading
import time
import traceback
from pathlib import Path

import tiltpile
from tiltpile.config import Config, ConfigError
from tiltpile.outputs import output_lock

MANIFEST = "ensemble.json"
LOCK = ".ensemble.lock"
FORMAT = "tiltpile-ensemble/1"
STATUSES = ("pending", "running", "done", "failed")  # of a run in the manifest
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "OPENBLAS_NUM_THREADS": "1"}
POLL = 0.25  # [s] between looks at finished futures and start/progress events
# The LocalCluster's own housekeeping, turned down: a run is one task of hours, so dask's
# statistical profiler (a stack sample of the busy thread every 10 ms), its event-loop tick
# (20 ms), system and memory monitors (0.5 s, 0.1 s) and work stealing (the scheduler queues
# these root tasks, worker-saturation 1.1) cost CPU and buy nothing. With the defaults the
# client and a worker running a 20 s task spent 2.3 s of CPU on them, with these 0.3 s (the
# study bench.dask_overhead, kept at f4398d3; notes/performance-log.md, "dask's housekeeping").
QUIET_DASK = {"distributed.worker.profile.enabled": False,
              "distributed.admin.tick.interval": "1s",
              "distributed.admin.system-monitor.interval": "5s",
              "distributed.worker.memory.monitor-interval": "1s",
              "distributed.scheduler.work-stealing": False}


def run_file(out_dir: str | Path, seed: int) -> Path:
    """The run file of ``seed`` in an ensemble directory: ``out_dir/run_{seed:04d}.h5``."""
    return Path(out_dir) / f"run_{seed:04d}.h5"


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


# -- validation (reads only) ------------------------------------------------------------------------

def _check_seeds(seeds) -> list[int]:
    try:
        seeds = list(seeds)
    except TypeError:
        raise ConfigError(f"seeds must be a list of integers, got {seeds!r}") from None
    if not seeds:
        raise ConfigError("no runs requested: give at least one seed (--runs >= 1)")
    out = []
    for s in seeds:
        try:
            if isinstance(s, bool):
                raise TypeError
            v = operator.index(s)  # ints and numpy integers, not floats
        except TypeError:
            raise ConfigError(f"seed {s!r} is not an integer") from None
        if v < 0:
            raise ConfigError(f"seed {v} is negative: seeds are non-negative integers (--first-seed >= 0)")
        from tiltpile.config import check_seed

        out.append(check_seed(v))
    if len(set(out)) != len(out):
        raise ConfigError("seeds repeat: each seed is one run")
    return out


def read_manifest(out_dir: str | Path) -> dict | None:
    """The manifest of ``out_dir``, or None if there is none; ConfigError if it cannot be read."""
    path = Path(out_dir) / MANIFEST
    if not path.exists():
        return None
    try:
        m = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise ConfigError(f"{path}: not a readable ensemble manifest ({e}); "
                          "move it away to start afresh") from None
    if not isinstance(m, dict) or m.get("format") != FORMAT or "config_hash" not in m:
        raise ConfigError(f"{path}: not a tiltpile ensemble manifest; move it away to start afresh")
    for key, kind in (("runs", dict), ("seeds", list), ("invocations", list)):
        if not isinstance(m.get(key), kind):
            raise ConfigError(f"{path}: damaged ensemble manifest (\"{key}\" is "
                              f"{'missing' if key not in m else repr(m[key])[:40]}, expected a "
                              f"{'table' if kind is dict else 'list'}); move it away to start afresh")
    if not all(isinstance(r, dict) and r.get("status") in STATUSES for r in m["runs"].values()):
        raise ConfigError(f"{path}: damaged ensemble manifest (a run without a valid status); "
                          "move it away to start afresh")
    return m


def _check_dir(config: Config, out_dir: Path, damaged: dict | None = None,
               seeds=(), verified: dict | None = None) -> dict | None:
    """Refuse a directory holding another configuration's ensemble; return its manifest if any.

    The run files of ``seeds`` are verified completely (``store.verify``); those that fail go
    into ``damaged`` (path -> first problem) instead of being refused. ``verified`` (file name ->
    [size, mtime_ns] of files already found sound, from the manifest or an earlier pass) spares
    re-reading an unchanged file; files found sound are added to it."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError(f"--out {out_dir} exists and is not a directory")
    if not out_dir.exists():
        from tiltpile.paths import check_output

        check_output(out_dir, "--out", directory=True)
    elif not os.access(out_dir, os.W_OK | os.X_OK):
        raise ConfigError(f"--out {out_dir} is not writable")
    manifest = read_manifest(out_dir) if out_dir.is_dir() else None
    h = config.hash()
    if manifest is not None and manifest["config_hash"] != h:
        raise ConfigError(
            f"{out_dir} holds an ensemble of another configuration (hash {manifest['config_hash'][:12]}, "
            f"this one {h[:12]}): use another --out directory, or the configuration in "
            f"{out_dir / MANIFEST}; nothing was changed")
    if out_dir.is_dir():
        from tiltpile.store import RunFileError, open_run, verify

        mine = {run_file(out_dir, s).name for s in seeds}
        for path in sorted(out_dir.glob("run_*.h5")):
            try:
                with open_run(path) as run:
                    other = run.config_hash
            except RunFileError as e:
                if damaged is not None and path.name in mine:
                    damaged[path] = str(e)
                    continue
                raise ConfigError(f"{e}; move it away to run an ensemble in {out_dir}") from None
            if other == h and damaged is not None and path.name in mine:
                st = path.stat()
                stamp = [st.st_size, st.st_mtime_ns]
                if verified is not None and verified.get(path.name) == stamp:
                    continue  # read in full and found sound, unchanged since
                problems = verify(path)
                if problems:
                    damaged[path] = f"{path}: {problems[0]}"
                elif verified is not None:
                    verified[path.name] = stamp
            if other != h:
                raise ConfigError(f"{path} is a run of another configuration (hash {other[:12]}, this one "
                                  f"{h[:12]}): use another --out directory; nothing was changed")
    return manifest


# -- manifest ---------------------------------------------------------------------------------------

def _versions() -> dict:
    import dask
    import distributed
    import h5py
    import numba
    import numpy

    return {"tiltpile": tiltpile.__version__, "python": sys.version.split()[0], "numpy": numpy.__version__,
            "numba": numba.__version__, "h5py": h5py.__version__, "dask": dask.__version__,
            "distributed": distributed.__version__}


def _new_run(seed: int) -> dict:
    return {"seed": seed, "file": run_file("", seed).name, "status": "pending", "error": None,
            "traceback": None, "attempts": 0, "started": None, "finished": None, "seconds": None,
            "worker": None}


class _Manifest:
    """The manifest dict plus an atomic, thread-safe ``save``."""

    def __init__(self, path: Path, data: dict):
        self.path, self.data = path, data
        self.lock = threading.Lock()

    def run(self, seed: int) -> dict:
        return self.data["runs"][str(seed)]

    def save(self) -> None:
        """Write the manifest atomically; a failed write (a full disk) leaves the previous
        manifest and no temporary file, and raises ``store.RunWriteError`` (one line)."""
        with self.lock:
            self.data["updated"] = _now()
            text = json.dumps(self.data, indent=1, sort_keys=False)
            tmp = self.path.with_name(self.path.name + ".tmp")
            try:
                with open(tmp, "w") as f:
                    f.write(text + "\n")
                    f.flush()
                    os.fsync(f.fileno())
                os.replace(tmp, self.path)
            except OSError as e:
                from tiltpile.store import write_error

                tmp.unlink(missing_ok=True)
                raise write_error(e, self.path) from None


def _merge_manifest(old: dict | None, config: Config, seeds: list[int], out_dir: Path,
                    verified: dict | None = None) -> dict:
    m = old or {"format": FORMAT, "config_hash": config.hash(), "config": json.loads(config.to_json()),
                "seeds": [], "runs": {}, "created": _now(), "invocations": []}
    m["tiltpile_version"] = tiltpile.__version__
    m["versions"] = _versions()
    m["seeds"] = sorted(set(m["seeds"]) | set(seeds))
    from tiltpile.store import remove_stale_checkpoint

    for s in seeds:
        r = m["runs"].setdefault(str(s), _new_run(s))
        remove_stale_checkpoint(run_file(out_dir, s))  # a kill between the rename and its removal
        if verified and run_file(out_dir, s).name in verified:
            r["verified"] = verified[run_file(out_dir, s).name]  # [size, mtime_ns] found sound
        if run_file(out_dir, s).exists():
            r["status"] = "done"
        elif r["status"] != "pending":  # running (interrupted) or failed: try again
            r["status"] = "pending"
    return m


# -- numba ------------------------------------------------------------------------------------------

def warm_numba_cache() -> float:
    """Compile (or load) the simulator's kernels in this process; returns the seconds it took.

    Steps a two-grain system (one resting on the floor, one on top of it) so ``sim.step.advance``
    and every kernel it calls are compiled with the argument types of a real run; with
    ``cache=True`` the code lands in numba's cache (``NUMBA_CACHE_DIR``) for the workers to load.
    """
    import numpy as np

    from tiltpile.sim.rng import make_state
    from tiltpile.sim.solver import SWEEPS
    from tiltpile.sim.step import System

    t0 = time.perf_counter()
    radius = np.array([0.5, 0.5])
    pos = np.array([[2.0, 0.5], [2.0, 1.5]])
    inv_mass = 1.0 / (np.pi * radius**2)
    sysm = System(radius, np.zeros(2, bool), pos, inv_mass, make_state(0), box_length=4.0, dt=0.01,
                  alert=0.1, mu=0.5, mu_wall=0.5, tol=1e-6, max_iter=50, mode=SWEEPS["forward"])
    sysm.advance(2, 0.0, 0.1)
    sysm.contacts()
    return time.perf_counter() - t0


def _cache_misses() -> int:
    """Kernels this process compiled rather than loaded from numba's cache."""
    from tiltpile.sim import step

    try:
        return int(sum(step.advance.stats.cache_misses.values()))
    except AttributeError:  # a numba without dispatcher stats
        return -1


# -- the task (runs in a worker) --------------------------------------------------------------------

def _run_one(config: Config, seed: int, path: str, topic: str) -> dict:
    """One run on a worker: announce the start, simulate (resuming), return the summary."""
    from tiltpile.runner import simulate
    from tiltpile.sim.protocol import SimulationError
    from tiltpile.store import RunExistsError, RunFileError

    started = _now()
    try:
        from distributed import get_worker

        worker = get_worker()
        address = worker.address
        log = worker.log_event
    except (ImportError, ValueError):
        address, log = "local", None
    if log is not None:
        log(topic, {"seed": seed, "event": "start", "time": started, "worker": address})
    if Path(path).exists():  # finished meanwhile (by a task of an earlier, killed client)
        return {"seed": seed, "path": path, "started": started, "finished": _now(), "worker": address,
                "seconds": 0.0, "skipped": True}
    on_progress = _progress_sender(log, topic, seed) if log is not None else None
    try:
        summary = simulate(config, seed, path, progress=False, resume=True, on_progress=on_progress,
                           overwrite=False)
    except RunExistsError:  # finished by another process while this task waited
        return {"seed": seed, "path": path, "started": started, "finished": _now(), "worker": address,
                "seconds": 0.0, "skipped": True}
    except (RunFileError, SimulationError) as e:
        # an expected failure (a full disk, a busy file, a health stop): returned, not raised, so the
        # worker does not log it as a crash with its traceback; the manifest records it as failed
        return {"seed": seed, "failed": True, "error": f"{type(e).__name__}: {e}",
                "traceback": traceback.format_exc(), "started": started, "finished": _now(),
                "worker": address}
    summary.update(started=started, finished=_now(), worker=address, numba_cache_misses=_cache_misses())
    return summary


def _progress_sender(log, topic: str, seed: int, every: float = 2.0):
    """A ``runner.simulate(on_progress=...)`` callback sending the run's angle at most every ``every`` s."""
    last = [-math.inf]

    def send(ev) -> None:
        t = time.monotonic()
        if t - last[0] >= every:
            last[0] = t
            log(topic, {"seed": seed, "event": "progress", "phase": ev.phase, "theta": float(ev.theta_deg)})

    return send


# -- the ensemble (client side) ---------------------------------------------------------------------

@contextlib.contextmanager
def _client(scheduler, workers: int | None, n_tasks: int):
    from distributed import Client, LocalCluster

    if scheduler is not None:
        address = getattr(scheduler, "scheduler_address", scheduler)  # a dask-jobqueue cluster works too
        try:
            client = Client(address, timeout="20s")
        except (OSError, TimeoutError) as e:
            raise ConfigError(f"cannot reach the dask scheduler at {address} ({e})") from None
        with client:
            yield client, str(address)
        return
    n = workers or max(1, min(os.cpu_count() or 1, n_tasks))
    env = dict(WORKER_ENV)
    if os.environ.get("NUMBA_CACHE_DIR"):
        env["NUMBA_CACHE_DIR"] = os.environ["NUMBA_CACHE_DIR"]
    import dask

    with dask.config.set(QUIET_DASK), \
            LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                         env=env) as cluster, Client(cluster) as client:
        yield client, f"LocalCluster({n} workers)"
        _quiet_teardown(client)    # on the way out of a finished ensemble, not of an interrupted one


def _quiet_teardown(client) -> None:
    """Silence dask's loggers in our LocalCluster's worker processes before it is closed. A
    worker's heartbeat can meet the scheduler's closed connection while the cluster shuts down;
    dask then logs an error with a traceback to the ensemble's stderr after every run's result
    is in, below the ensemble's one-line report. Best effort: a worker that is gone already has
    nothing to say."""
    with contextlib.suppress(Exception):
        client.run(_silence_dask_logs, on_error="ignore")


def _silence_dask_logs() -> None:
    import logging

    names = ["distributed"] + [k for k in logging.root.manager.loggerDict if k.startswith("distributed.")]
    for name in names:
        logging.getLogger(name).setLevel(logging.CRITICAL)


def run_ensemble(config: Config, seeds, out_dir: str | Path, *, scheduler=None, workers: int | None = None,
                 progress: bool = True) -> dict:
    """Run one pile per seed into ``out_dir`` on dask.distributed; return the final manifest.

    ``scheduler``: None for a LocalCluster of ``workers`` processes (default: one per core, at most
    one per run), or the address of an existing scheduler (``tcp://host:port``) or a cluster object
    with ``scheduler_address``. ``progress``: one tqdm bar over runs on stderr (readable in a log).
    Raises ConfigError, having written nothing, on bad input or a directory of another configuration,
    and ``outputs.OutputBusy`` (one line) while another ensemble runs in ``out_dir``.
    A failed run does not raise: it is ``status: failed`` in the manifest (see ``failed_runs``).
    """
    if not isinstance(config, Config):
        raise ConfigError(f"config must be a tiltpile.config.Config, got {type(config).__name__}")
    seeds = _check_seeds(seeds)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"--workers must be a positive integer, got {workers!r}")
    out_dir = Path(out_dir)
    damaged: dict = {}
    verified = _verified(out_dir)
    old = _check_dir(config, out_dir, damaged, seeds, verified)
    todo = [s for s in seeds if not run_file(out_dir, s).exists() or run_file(out_dir, s) in damaged]
    recorded = old is not None and all(old["runs"].get(str(s), {}).get("status") == "done" for s in seeds)
    if not todo and recorded:
        _report(old, seeds, progress, out_dir)
        return old  # everything done and recorded: touch nothing

    t_start, started = time.perf_counter(), _now()
    with contextlib.ExitStack() as stack:
        client = engine = None
        if todo:
            client, engine = stack.enter_context(_client(scheduler, workers, len(todo)))
        out_dir.mkdir(parents=True, exist_ok=True)
        stack.enter_context(output_lock(out_dir, LOCK, "tiltpile ensemble"))
        damaged = {}
        old = _check_dir(config, out_dir, damaged, seeds, verified)  # again, now that we hold the lock
        _move_aside(damaged)
        man = _Manifest(out_dir / MANIFEST, _merge_manifest(old, config, seeds, out_dir, verified))
        todo = [s for s in seeds if man.run(s)["status"] != "done"]
        invocation = {"started": started, "engine": engine, "seeds": todo}
        man.data["invocations"].append(invocation)
        man.save()
        try:
            if todo:
                invocation["numba_warmup_seconds"] = round(warm_numba_cache(), 3)
                _execute(client, config, todo, out_dir, man, progress, n_total=len(seeds))
        finally:
            invocation["finished"] = _now()
            invocation["seconds"] = round(time.perf_counter() - t_start, 3)
            man.save()
    _report(man.data, seeds, progress, out_dir)
    return man.data


def _verified(out_dir: Path) -> dict:
    """File name -> [size, mtime_ns] of the run files the manifest records as read in full and found
    sound (``verified``); a file changed since (size or mtime) is verified again."""
    try:
        m = read_manifest(out_dir) if out_dir.is_dir() else None
    except ConfigError:
        return {}
    return {r["file"]: r["verified"] for r in (m or {}).get("runs", {}).values()
            if isinstance(r, dict) and isinstance(r.get("verified"), list) and "file" in r}


def _verify_new(r: dict, path: Path) -> None:
    """Read a run file just finished in full (from the page cache, as a rule) and record it as
    ``verified`` ([size, mtime_ns]), or the run as failed if it is already damaged."""
    if r["status"] != "done" or not path.exists():
        return
    from tiltpile.store import verify

    problems = verify(path)
    if problems:
        r.update(status="failed", error=f"{path}: {problems[0]} (right after it was written)")
        return
    st = path.stat()
    r["verified"] = [st.st_size, st.st_mtime_ns]


def _move_aside(damaged: dict) -> None:
    """Move run files that failed verification to ``NAME.damaged`` (kept for inspection), saying so;
    their seeds are then run again."""
    for path, problem in sorted(damaged.items()):
        target = path.with_name(path.name + ".damaged")
        os.replace(path, target)
        print(f"tiltpile ensemble: {problem}: moved to {target.name}, running its seed again",
              file=sys.stderr)


def _execute(client, config: Config, todo: list[int], out_dir: Path, man: _Manifest, progress: bool,
             n_total: int) -> None:
    from distributed import as_completed
    from tqdm.auto import tqdm

    topic = f"tiltpile-ensemble-{config.hash()[:12]}-{os.getpid()}-{time.monotonic_ns()}"
    events: list[dict] = []
    events_lock = threading.Lock()

    def on_event(event) -> None:
        with events_lock:
            events.append(event[1])

    client.subscribe_topic(topic, on_event)
    tty = sys.stderr.isatty()
    bar = tqdm(total=n_total, initial=n_total - len(todo), unit="run", desc="ensemble",
               file=sys.stderr if tty else _LogLines(sys.stderr), disable=not progress,
               mininterval=0.5 if tty else 30.0, dynamic_ncols=tty, ascii=not tty,
               bar_format="{desc}: {n}/{total} runs |{bar}| [{elapsed}<{remaining}]{postfix}")
    angles: dict[int, str] = {}
    futures = {}
    for s in todo:
        fut = client.submit(_run_one, config, s, str(run_file(out_dir, s).resolve()), topic, pure=False,
                            key=f"tiltpile-run-{s:04d}-{topic[-12:]}")
        futures[fut] = s
    ac = as_completed(futures, with_results=False)
    ended: set[int] = set()
    try:
        while not ac.is_empty():
            with events_lock:
                batch, events[:] = list(events), []
            changed = False
            for ev in batch:
                s, r = ev["seed"], man.run(ev["seed"])
                if ev["event"] == "start" and s not in ended:
                    r.update(status="running", started=ev["time"], worker=ev["worker"], error=None,
                             traceback=None, attempts=r["attempts"] + 1)
                    angles[s] = "running"
                    changed = True
                elif ev["event"] == "progress" and s not in ended:
                    angles[s] = f"{ev['theta']:.1f}°" if ev["phase"] == "tilt" else ev["phase"]
            finished = ac.next_batch(block=False)  # after the events: a run's start comes before its end
            ended |= {futures[f] for f in finished}
            for fut in finished:
                s = futures[fut]
                _record(man.run(s), fut)
                _verify_new(man.run(s), run_file(out_dir, s))
                angles.pop(s, None)
                r = man.run(s)
                line = (f"seed {s}: done in {r['seconds']:.1f} s" if r["status"] == "done"
                        else f"seed {s}: FAILED: {r['error']}")
                bar.update(1)
                if progress:
                    bar.write(line, file=bar.fp)
                changed = True
            if changed:
                man.save()
            bar.set_postfix_str(" ".join(f"{s}:{a}" for s, a in sorted(angles.items())), refresh=False)
            if not finished:
                time.sleep(POLL)
    finally:
        bar.close()
        with contextlib.suppress(Exception):
            client.unsubscribe_topic(topic)


class _LogLines:
    """A file for tqdm when stderr is not a terminal: each refresh becomes one plain line."""

    def __init__(self, f):
        self.f = f

    def write(self, s: str) -> None:
        text = s.replace("\r", "").rstrip()
        if text:
            self.f.write(text + "\n")

    def flush(self) -> None:
        self.f.flush()


def _record(r: dict, fut) -> None:
    """Copy a finished future's outcome into its manifest entry."""
    if fut.status == "finished":
        summary = fut.result()
        if r["status"] == "pending":  # its start event was not seen
            r["attempts"] += 1
        if summary.get("failed"):
            r.update(status="failed", error=summary["error"], traceback=summary["traceback"],
                     finished=summary["finished"], worker=summary.get("worker"))
            return
        r.update(status="done", error=None, traceback=None,
                 **{k: v for k, v in summary.items() if k not in ("path", "seed")})
        if r.get("seconds") is not None:
            r["seconds"] = round(float(r["seconds"]), 3)
        return
    try:
        exc = fut.exception()
        tb = fut.traceback()
        text = f"{type(exc).__name__}: {exc}"
        tb_text = "".join(traceback.format_exception(type(exc), exc, tb))
    except Exception as e:  # cancelled futures and the like
        text, tb_text = f"{fut.status}: {type(e).__name__}: {e}", None
    if r["status"] == "pending":
        r["attempts"] += 1
    r.update(status="failed", error=text, traceback=tb_text, finished=_now())


def failed_runs(manifest: dict) -> list[int]:
    """Seeds whose last attempt failed."""
    return sorted(int(s) for s, r in manifest["runs"].items() if r["status"] == "failed")


def _report(manifest: dict, seeds: list[int], progress: bool, out_dir: Path) -> None:
    if not progress:
        return
    st = [manifest["runs"].get(str(s), {}).get("status", "pending") for s in seeds]
    print(f"ensemble {out_dir}: {st.count('done')} done, {st.count('failed')} failed of {len(seeds)} runs",
          file=sys.stderr)
