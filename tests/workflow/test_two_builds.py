"""Two builds on one output at once (issue 55 item 2): one waits for the other or is refused in
one line naming what is busy, and what is written is whole and what a single build writes.

* the lock itself (``tiltpile.outputs``): a second holder is refused in one line naming the
  directory, the holder and the lock file, or waits, saying so in one line; the kernel releases
  the lock when its holder is killed; the Makefile's ``hold`` keeps it until the process it holds
  it for exits;
* files replaced whole (``replaced_whole``): an error mid-write leaves the old file, no temporary;
* ``compute_observables`` and ``tiltpile record`` wait for another writer of the same cache or
  records directory, then compute and write only what it left undone;
* two `make` of one smoke figure on the same figures directory started together: one is refused
  in one line, and the figure is byte for byte what a build alone writes.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from makehelpers import MAKE_ENV

from tiltpile import config
from tiltpile.outputs import LockHeld, OutputBusy, lock_file, output_lock, replaced_whole, unlock_file
from tiltpile.runner import simulate

ROOT = Path(__file__).resolve().parents[2]
TINY = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=2.0"]
ENV = dict(os.environ, NUMBA_CACHE_DIR=os.environ.get("NUMBA_CACHE_DIR", str(ROOT / ".venv" / "numba-cache")))

# a first writer: takes DIR/NAME as `what`, says so, and holds it until killed
HOLDER = ("import sys, time; from tiltpile.outputs import output_lock\n"
          "with output_lock(sys.argv[1], sys.argv[2], sys.argv[3]):\n"
          "    print('held', flush=True); time.sleep(600)")


def _holder(directory: Path, name: str, what: str) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-c", HOLDER, str(directory), name, what],
                         stdout=subprocess.PIPE, text=True, env=ENV)
    assert p.stdout.readline().strip() == "held"
    return p


def _kill(p: subprocess.Popen) -> None:
    p.send_signal(signal.SIGKILL)   # nothing runs after it: the kernel alone releases the lock
    p.wait()


def _gone(path: Path, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while path.exists():
        if time.monotonic() > end:
            return False
        time.sleep(0.05)
    return True


# -- the lock -------------------------------------------------------------------------------------

def test_a_second_holder_is_refused_in_one_line_until_the_first_dies(tmp_path):
    d = tmp_path / "records"
    first = _holder(d, ".record.lock", "tiltpile record")
    try:
        with pytest.raises(OutputBusy) as e:
            with output_lock(d, ".record.lock", "tiltpile record"):
                pass
        msg = str(e.value)
        assert "\n" not in msg
        assert msg.startswith(f"{d} is busy: tiltpile record (pid {first.pid} on ")
        assert f"(lock {d / '.record.lock'})" in msg and "nothing was changed" in msg
    finally:
        _kill(first)
    with output_lock(d, ".record.lock", "tiltpile record") as lock:   # free once its holder died
        assert lock.read_text().startswith(f"tiltpile record (pid {os.getpid()} on ")
    assert list(d.iterdir()) == []                                      # the lock file removed


def test_a_waiting_holder_says_so_in_one_line_and_goes_on_when_the_first_is_done(tmp_path, capfd):
    d = tmp_path / "observables"
    first = _holder(d, ".observables.lock", "an observables computation")
    took = threading.Event()

    def second():
        with output_lock(d, ".observables.lock", "another", wait=True):
            took.set()

    t = threading.Thread(target=second)
    try:
        t.start()
        assert not took.wait(1.0)                                       # waits while it is held
    finally:
        _kill(first)
    t.join(30)
    assert took.is_set()
    lines = capfd.readouterr().err.splitlines()
    assert lines == [f"{d} is busy: an observables computation (pid {first.pid} on "
                     f"{socket.gethostname()}) is writing it (lock {d / '.observables.lock'}); "
                     "waiting for it to finish"]


def test_the_lock_of_one_process_taken_twice_is_an_error_not_a_wait_forever(tmp_path):
    with output_lock(tmp_path, ".x.lock", "a"):
        with pytest.raises(RuntimeError, match="already held by this process"):
            with output_lock(tmp_path, ".x.lock", "a", wait=True):
                pass


def test_a_lock_file_is_never_seen_held_without_its_holder(tmp_path, monkeypatch):
    """The moment a lock is taken, the file at the lock's path (if any) already names a holder:
    a second process that finds it held reads who holds it, never an empty note (a make once
    said "another process" because it read the lock between its creation and its note). Also
    for a lock file left by a holder that died, whose longer note the new one replaces."""
    import fcntl

    lock = tmp_path / ".build.lock"
    real, seen = fcntl.flock, []

    def flock(fd, op):
        real(fd, op)
        if op & fcntl.LOCK_EX and lock.exists():
            seen.append(lock.read_text())

    monkeypatch.setattr(fcntl, "flock", flock)
    fd = lock_file(lock, "make figures (pid 1 on here)")
    assert lock.read_text() == "make figures (pid 1 on here)\n"
    os.close(fd)                                      # dies without removing it: left behind
    fd = lock_file(lock, "a (pid 2 on here)")
    assert lock.read_text().rstrip(" ") == "a (pid 2 on here)\n"   # the older note replaced whole
    unlock_file(lock, fd)
    assert seen and all(note.strip() for note in seen), seen


def test_without_o_tmpfile_the_lock_is_written_under_a_hidden_name_and_leaves_nothing_else(
        tmp_path, monkeypatch):
    monkeypatch.delattr(os, "O_TMPFILE")
    lock = tmp_path / ".build.lock"
    fd = lock_file(lock, "make figures (pid 3 on here)")
    assert [p.name for p in tmp_path.iterdir()] == [".build.lock"]
    assert lock.read_text() == "make figures (pid 3 on here)\n"
    with pytest.raises(LockHeld, match=r"held by make figures \(pid 3 on here\)"):
        lock_file(lock, "second")
    unlock_file(lock, fd)
    assert list(tmp_path.iterdir()) == []


def test_a_lock_taken_and_released_in_a_loop_always_names_its_holder_to_another_process(tmp_path):
    lock = tmp_path / ".build.lock"
    taker = subprocess.Popen(
        [sys.executable, "-c", "import sys; from tiltpile.outputs import LockHeld, lock_file, unlock_file\n"
         "for _ in range(3000):\n    try:\n        fd = lock_file(sys.argv[1], 'taker (pid 7 on h)')\n"
         "    except LockHeld:\n        continue\n    unlock_file(sys.argv[1], fd)",
         str(lock)], env=ENV)
    notes = []
    try:
        while taker.poll() is None:
            try:
                fd = lock_file(lock, "reader")
            except LockHeld as e:
                notes.append(e.holder)
            else:
                unlock_file(lock, fd)
    finally:
        taker.kill()
        taker.wait()
    assert notes, "the reader never found the lock held"
    assert set(notes) == {"taker (pid 7 on h)"}, {n for n in notes if n != "taker (pid 7 on h)"}


def test_make_holds_the_figures_lock_until_make_exits(tmp_path):
    """`python -m tiltpile.outputs hold`, as the Makefile runs it with make's pid: returns at
    once; a second is refused in one line naming the make; once that process is gone (killed),
    the lock is released and its file removed."""
    d = tmp_path / "figs"
    lock = d / ".build.lock"
    make = subprocess.Popen(["sleep", "600"])        # stands for make

    def hold(pid):
        return subprocess.run([sys.executable, "-m", "tiltpile.outputs", "hold", str(d), ".build.lock",
                               "--what", "make figures", "--pid", str(pid)],
                              capture_output=True, text=True, timeout=60, env=ENV)

    try:
        r = hold(make.pid)
        assert r.returncode == 0 and r.stdout == r.stderr == ""
        assert lock.read_text() == f"make figures (pid {make.pid} on {socket.gethostname()})\n"
        r = hold(os.getpid())
        assert r.returncode == 1
        assert r.stderr.splitlines() == [
            f"{d} is busy: make figures (pid {make.pid} on {socket.gethostname()}) is writing it "
            f"(lock {lock}); wait for it to finish or stop it (nothing was changed)"]
    finally:
        _kill(make)
    assert _gone(lock)
    fd = lock_file(lock)                              # free
    unlock_file(lock, fd)


def test_a_file_is_replaced_whole_or_not_at_all(tmp_path):
    path = tmp_path / "fig.json"
    path.write_text("old\n")
    with pytest.raises(OSError):
        with replaced_whole(path) as tmp:
            tmp.write_text("half")
            raise OSError(28, "No space left on device")
    assert path.read_text() == "old\n" and sorted(tmp_path.iterdir()) == [path]
    with replaced_whole(path) as tmp:
        assert tmp.parent == tmp_path and tmp.name == f".fig.json.{os.getpid()}.tmp"
        tmp.write_text("new\n")
    assert path.read_text() == "new\n" and sorted(tmp_path.iterdir()) == [path]


# -- the commands that wait -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("tiny")
    simulate(config.load("smoke", overrides=TINY), 3, d / "run_0003.h5", progress=False)
    return d / "run_0003.h5"


def _in_thread(fn) -> tuple[threading.Thread, dict]:
    out: dict = {}

    def run():
        try:
            out["value"] = fn()
        except BaseException as e:   # handed to the test
            out["error"] = e

    t = threading.Thread(target=run)
    t.start()
    return t, out


def test_observables_wait_for_another_computation_of_the_same_cache(tmp_path, tiny_run, capfd):
    from tiltpile.analysis import compute_observables
    from tiltpile.analysis.observables import LOCK

    d = tmp_path / "ens"
    d.mkdir()
    shutil.copy2(tiny_run, d)
    cache = d / "observables"
    first = _holder(cache, LOCK, "an observables computation")
    try:
        t, out = _in_thread(lambda: compute_observables(d, workers=1, progress=False))
        t.join(3.0)
        assert t.is_alive() and sorted(p.name for p in cache.iterdir()) == [LOCK]   # nothing computed
    finally:
        _kill(first)
    t.join(300)
    assert "error" not in out, out.get("error")
    assert list(out["value"]["status"]) == ["computed"]
    assert sorted(p.name for p in cache.iterdir()) == ["run_0003.npz"]              # no lock, no temporary
    err = [line for line in capfd.readouterr().err.splitlines() if "busy" in line]
    assert err == [f"{cache} is busy: an observables computation (pid {first.pid} on "
                   f"{socket.gethostname()}) is writing it (lock {cache / LOCK}); waiting for it to finish"]
    # the second of two finds what the first computed: nothing computed again
    assert list(compute_observables(d, workers=1, progress=False)["status"]) == ["cached"]


def test_record_waits_for_another_writer_of_the_same_records(tmp_path, tiny_run, capfd):
    from tiltpile.cli import main
    from tiltpile.figures.records import LOCK

    d, recs = tmp_path / "ens", tmp_path / "records"
    d.mkdir()
    shutil.copy2(tiny_run, d)
    first = _holder(recs, LOCK, "a records writer")
    try:
        t, out = _in_thread(lambda: main(["record", str(d), "--out", str(recs), "--workers", "1",
                                          "--quiet"]))
        t.join(3.0)
        assert t.is_alive() and sorted(p.name for p in recs.iterdir()) == [LOCK]     # nothing written
    finally:
        _kill(first)
    t.join(300)
    assert out == {"value": 0}
    assert sorted(p.name for p in recs.iterdir()) == ["run_0003.npz"]
    captured = capfd.readouterr()
    assert [line for line in captured.err.splitlines() if "busy" in line] == [
        f"{recs} is busy: a records writer (pid {first.pid} on {socket.gethostname()}) is writing it "
        f"(lock {recs / LOCK}); waiting for it to finish"]
    assert "1 written, 0 up to date" in captured.out


# -- two makes at once ------------------------------------------------------------------------------

FIGURE = "fig5_cluster_sizes"


def _make_args(data: Path, figs: Path, executed: Path, tmp: Path) -> list[str]:
    """One figure of the smoke preset from the session's three smoke runs (seeds 1-3), every
    output in tmp: the ensemble and observables steps run (and find everything done)."""
    return ["make", f"{figs}/{FIGURE}.json", "PRESET=smoke", "RUNS=3", "ENSEMBLE_ARGS=--first-seed 1",
            f"DATA={data}", f"BASE_DATA={data}", f"FIGURES={figs}", f"EXECUTED={executed}",
            f"RECORDS={tmp}/no-records", f"REPORT={figs}/REPRODUCTION.md"]


@pytest.mark.slow
def test_two_makes_at_once_one_is_refused_in_one_line_and_the_figure_is_a_single_builds(
        tmp_path, smoke_ensemble):
    if not (ROOT / ".venv" / "bin" / "python").exists():
        pytest.skip("needs the checkout's .venv (make setup)")
    data = tmp_path / "data"
    shutil.copytree(smoke_ensemble, data, copy_function=shutil.copy2)   # times kept: caches stay fresh
    figs = tmp_path / "figs"
    both = [subprocess.Popen(_make_args(data, figs, tmp_path / f"executed-{k}", tmp_path), cwd=ROOT,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=MAKE_ENV)
            for k in (0, 1)]
    done = [(p.returncode, *outs) for p in both for outs in [p.communicate(timeout=1200)]]
    ok = [r for r in done if r[0] == 0]
    refused = [r for r in done if r[0] != 0]
    assert len(ok) == 1 and len(refused) == 1, [r[2][-2000:] for r in done]
    rc, out, err = refused[0]
    ours = [line for line in err.splitlines() if not line.startswith("make")]
    assert len(ours) == 1, err
    assert re.fullmatch(rf"{re.escape(str(figs))} is busy: make figures \(pid \d+ on .+\) is writing it "
                        rf"\(lock {re.escape(str(figs / '.build.lock'))}\); wait for it to finish or stop "
                        r"it \(nothing was changed\)", ours[0]), ours[0]
    assert "papermill" not in out and "tiltpile ensemble" not in out           # it did nothing
    assert f"papermill notebooks/{FIGURE}.ipynb" in ok[0][1]
    assert _gone(figs / ".build.lock")
    assert sorted(p.name for p in figs.iterdir()) == [f"{FIGURE}.{e}" for e in ("json", "pdf", "png")]

    alone = tmp_path / "alone"
    r = subprocess.run(_make_args(data, alone, tmp_path / "executed-alone", tmp_path), cwd=ROOT,
                       capture_output=True, text=True, timeout=1200, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr[-2000:]
    for ext in ("json", "png"):
        assert (figs / f"{FIGURE}.{ext}").read_bytes() == (alone / f"{FIGURE}.{ext}").read_bytes(), ext
