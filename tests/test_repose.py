"""The repose angle (``tiltpile.repose``, ``tiltpile repose``): the rebuilt pile continues its
run, the smoke pile slides and stops lower, the numbers repeat, and bad input is one line."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from tiltpile import repose as rp
from tiltpile.cli import main
from tiltpile.cli.repose import DEFAULTS
from tiltpile.runner import system_from_frame
from tiltpile.sim import protocol
from tiltpile.store import open_run

CHEAP = ["--ke-slide", "1", "--max-deg", "25.2"]  # never a slide: two frames, then "no slide"


@pytest.fixture(scope="module")
def measured(smoke_run):
    """``repose`` of the session's smoke run (seed 1, tilted to 25 deg), with default parameters."""
    return rp.repose(smoke_run[0])


def test_rebuilt_pile_continues_its_run(smoke_run):
    """frame_every steps from a rebuilt frame land on the next stored frame: the grains, their
    velocities and the impulses (warm start) are those of the run."""
    with open_run(smoke_run[0]) as run:
        for k in (50, 240):  # quiet (5 deg), and in the slide, where steps stop at the cap
            cfg, sysm = system_from_frame(run, k)
            p = cfg.protocol
            sysm.advance(p.frame_every, float(run.theta_deg[k]), p.tilt_per_step_deg)
            moved = np.abs(run.position(k + 1) - run.position(k)).max()
            err = np.abs(sysm.pos - run.position(k + 1)).max()
            assert err < (1e-12 if k == 50 else 1e-3 * moved), (k, err, moved)  # cold: 1e-4, 0.1 moved
            assert sysm.kinetic_energy() == pytest.approx(run.ke[k + 1], rel=1e-6 if k == 50 else 1e-2)


def test_the_rebuilt_frame_holds_the_stored_contacts(smoke_run):
    """The rebuilt System lists the frame's stored contacts again, walls included (run-file ids
    -1..-3 to the kernels' N + k and back), with their forces and states; from a path as from an
    open run; a frame the run does not have is one line."""
    path = smoke_run[0]
    with open_run(path) as run:
        k = run.n_frames - 1
        want = run.contacts(k)
        cfg, sysm = system_from_frame(run, -1)
        assert sysm.scalars.step == int(run.step[k]) and sysm.scalars.phase == "tilt"
        with pytest.raises(IndexError, match=f"frame {run.n_frames} out of range: the run has "
                                             f"{run.n_frames} frames"):
            system_from_frame(run, run.n_frames)
    got = sysm.contacts()
    assert (want[0][:, 1] < 0).any()  # the pile touches a wall
    order = [np.lexsort((p[:, 1], p[:, 0])) for p in (want[0], got[0])]
    np.testing.assert_array_equal(got[0][order[1]], want[0][order[0]])
    np.testing.assert_allclose(got[1][order[1]], want[1][order[0]], rtol=1e-12, atol=0)
    np.testing.assert_array_equal(got[2][order[1]], want[2][order[0]])
    _, again = system_from_frame(path, k)
    for name in ("pos", "rot", "vel", "ci", "cj", "c", "status"):
        np.testing.assert_array_equal(getattr(again, name), getattr(sysm, name), err_msg=name)


def test_the_smoke_pile_slides_then_stops_lower(measured, smoke_run, smoke_config):
    r = measured
    p = smoke_config.protocol
    assert r.outcome == "stopped" and r.seed == 1 and not r.error
    assert r.start_deg == pytest.approx(p.theta_max_deg)  # the run's frames establish no slide
    assert r.start_frame == protocol.n_frames(p) - 1
    assert 0 < r.stop_deg < r.slide_deg <= r.reverse_deg
    # the slide carried grains downhill (towards x = L): the stopped surface rises there, so it
    # lies flatter to the horizontal than the box
    assert 0 < r.surface_deg < r.stop_deg
    assert r.slide_deg <= r.start_deg + r.forward_steps * p.tilt_per_step_deg + 1e-9
    # the trace: forward frames, then the reverse ramp down to the stop, a frame every frame_every steps
    fwd, rev = r.direction == 1, r.direction == -1
    assert rev.sum() * p.frame_every == r.reverse_steps and fwd.sum() * p.frame_every == r.forward_steps
    assert np.all(r.direction[: fwd.sum()] == 1) and rev.sum() >= 5
    spacing = p.frame_every * p.tilt_per_step_deg
    np.testing.assert_allclose(np.diff(r.theta_deg[rev]), -spacing, atol=1e-9)
    assert r.theta_deg[rev][0] == pytest.approx(r.reverse_deg - spacing)
    # the stop: the first reverse frame of the last quiet span, which fills the span
    n_stop = rp.span_frames(rp.STOP_SPAN_DEG, p.frame_every, p.tilt_per_step_deg)
    ke_rev, th_rev = r.ke[rev], r.theta_deg[rev]
    assert np.all(ke_rev[-n_stop:] < rp.KE_STOP) and th_rev[-n_stop] == r.stop_deg
    assert np.any(ke_rev > rp.KE_SLIDE)  # the slide went on after the reversal
    assert rp.sustained_start(ke_rev, False, rp.KE_STOP, n_stop) == ke_rev.size - n_stop
    assert r.steps == r.forward_steps + r.reverse_steps and r.sweeps >= r.steps
    assert r.sweeps == r.sweeps_per_frame.sum()
    assert r.max_overlap < smoke_config.health.overlap_warn


def test_same_file_same_numbers(measured, smoke_run):
    again = rp.repose(smoke_run[0]).to_dict()
    first = measured.to_dict()
    assert again.pop("seconds") > 0 and first.pop("seconds") > 0
    assert again == first


def test_no_slide_below_max_deg(smoke_run):
    r = rp.repose(smoke_run[0], ke_slide=1.0, max_deg=25.2)
    assert r.outcome == "no slide" and math.isnan(r.slide_deg) and math.isnan(r.stop_deg)
    assert r.reverse_steps == 0 and np.all(r.direction == 1)
    assert r.theta_deg[-1] == pytest.approx(25.2) and r.ke.size == 2


def test_a_slide_the_run_established_turns_back_where_it_did(smoke_run):
    """With a threshold the run's own frames pass for long enough, the continuation starts at the
    frame that establishes the slide and reverses at once; ``from_last`` starts at the last."""
    with open_run(smoke_run[0]) as run:
        ke, theta, last = run.ke / (~run.fixed).sum(), run.theta_deg, run.n_frames - 1
    n = rp.span_frames(0.5, 10, 0.01)
    first = rp.sustained_start(ke, True, 1e-4, n)
    assert 0 < first < last - n  # the smoke run of seed 1 passes 1e-4 for 0.5 deg before it ends
    k = first + n - 1
    r = rp.repose(smoke_run[0], ke_slide=1e-4, slide_span_deg=0.5, min_deg=theta[k] - 0.25)
    assert r.start_frame == k and r.forward_steps == 0
    assert r.start_deg == r.reverse_deg == pytest.approx(theta[k], abs=1e-9)
    assert r.slide_deg == pytest.approx(theta[first], abs=1e-9)
    np.testing.assert_allclose(r.theta_deg, theta[k] - [0.1, 0.2, 0.3], atol=1e-9)
    late = rp.repose(smoke_run[0], ke_slide=1e-4, slide_span_deg=0.5, min_deg=24.85, from_last=True)
    assert late.start_frame == last and late.forward_steps == 0
    assert late.reverse_deg == pytest.approx(theta[last], abs=1e-9)
    trailing = rp.sustained_start(ke[::-1], False, 1e-4, 1)  # frames above 1e-4 at the end
    assert late.slide_deg == pytest.approx(theta[last - trailing + 1], abs=1e-9)


def test_sustained_start():
    ke = [1e-3, 1e-6, 1e-6, 1e-4, 1e-6, 1e-6, 1e-6, 1e-6]
    assert rp.sustained_start(ke, False, 1e-5, 3) == 4
    assert rp.sustained_start(ke, False, 1e-5, 2) == 1
    assert rp.sustained_start(ke, False, 1e-5, 5) == -1
    assert rp.sustained_start(ke, True, 1e-5, 1) == 0
    assert rp.span_frames(0.5, 10, 0.01) == 5 and rp.span_frames(1.0, 25, 0.002) == 20
    assert rp.span_frames(0.01, 10, 0.01) == 1


@pytest.mark.parametrize("kw, message", [
    (dict(ke_stop=2e-3), "ke_stop = 0.002 must be below ke_slide = 0.001"),
    (dict(ke_slide=-1.0), "ke_slide must be a finite number > 0"),
    (dict(stop_span_deg=float("nan")), "stop_span_deg must be a finite number > 0"),
    (dict(max_deg=95.0), "0 <= min_deg < max_deg <= 90"),
])
def test_bad_parameters_are_refused(kw, message, smoke_run):
    with pytest.raises(ValueError, match=message):
        rp.repose(smoke_run[0], **kw)


def test_summary_over_runs():
    def fake(stop, slide, outcome="stopped"):
        r = rp._failed("x", 0, {}, "")
        r.outcome, r.stop_deg, r.slide_deg, r.steps, r.sweeps = outcome, stop, slide, 10, 100
        return r

    runs = [fake(15.0, 21.0), fake(17.0, 22.0), fake(16.0, 20.0), fake(math.nan, math.nan, "no slide")]
    s = rp.summarize(runs)
    assert s["runs"] == 4 and s["outcomes"]["stopped"] == 3 and s["outcomes"]["no slide"] == 1
    assert s["stop_deg"]["estimate"] == pytest.approx(16.0) and s["stop_deg"]["n"] == 3
    assert 15.0 <= s["stop_deg"]["low"] < 16.0 < s["stop_deg"]["high"] <= 17.0
    assert s["slide_minus_stop_deg"]["estimate"] == pytest.approx(5.0)
    assert s["sweeps"] == 400
    json.dumps(s, allow_nan=False)
    assert rp.summarize([fake(math.nan, math.nan, "failed")])["stop_deg"]["estimate"] is None


# -- the command ---------------------------------------------------------------------------------


def test_cli_defaults_are_the_library_defaults():
    assert DEFAULTS == dict(ke_slide=rp.KE_SLIDE, ke_stop=rp.KE_STOP, slide_span=rp.SLIDE_SPAN_DEG,
                            stop_span=rp.STOP_SPAN_DEG, max_deg=rp.MAX_DEG)


def test_cli_writes_the_measurement(measured, smoke_run, tmp_path, capsys):
    out = tmp_path / "repose.json"
    assert main(["repose", str(smoke_run[0]), "--json", str(out), "--quiet"]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("run_0001.h5: slide from") and f"flow stops at {measured.stop_deg:.2f} deg" in line
    doc = json.loads(out.read_text())
    assert doc["format"] == "tiltpile-repose/1" and doc["params"]["ke_stop"] == rp.KE_STOP
    (got,) = doc["runs"]
    want = measured.to_dict()
    got.pop("seconds"), want.pop("seconds")
    assert got == want
    assert doc["summary"]["stop_deg"]["estimate"] == measured.stop_deg
    assert [p.name for p in tmp_path.iterdir()] == ["repose.json"]  # no temporary left


def test_cli_on_a_directory_with_workers(smoke_run, tmp_path, capsys):
    for s in (1, 2):
        shutil.copy(smoke_run[0], tmp_path / f"run_000{s}.h5")
    out = tmp_path / "r.json"
    assert main(["repose", str(tmp_path), *CHEAP, "--workers", "2", "--quiet", "--json", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sorted(ln.split(":")[0] for ln in lines[:2]) == ["run_0001.h5", "run_0002.h5"]
    assert all("no slide from 25.00 up to 25.20 deg" in ln for ln in lines[:2])
    assert lines[2].startswith("stop angle none") and "0 of 2 runs stopped, 2 no slide" in lines[2]
    doc = json.loads(out.read_text())
    assert [r["run"].rsplit("/", 1)[1] for r in doc["runs"]] == ["run_0001.h5", "run_0002.h5"]
    assert doc["runs"][0]["theta_deg"] == doc["runs"][1]["theta_deg"] == [25.1, 25.2]


def _one_line_error(capsys, argv, status=2) -> str:
    assert main(argv) == status
    cap = capsys.readouterr()
    assert cap.out == "" and len(cap.err.strip().splitlines()) == 1, cap.err
    assert cap.err.startswith("tiltpile repose: error: ")
    return cap.err


@pytest.mark.parametrize("args, message", [
    (["--ke-stop", "0"], "--ke-stop must be a finite number > 0, got 0"),
    (["--ke-slide", "nan"], "--ke-slide must be a finite number > 0"),
    (["--ke-stop", "0.01"], "--ke-stop 0.01 must be below --ke-slide 0.001"),
    (["--stop-span", "-1"], "--stop-span must be a finite number > 0"),
    (["--max-deg", "120"], "--max-deg must be in (0, 90]"),
    (["--workers", "0"], "--workers must be at least 1"),
])
def test_cli_refuses_bad_numbers(smoke_run, tmp_path, capsys, args, message):
    out = tmp_path / "r.json"
    err = _one_line_error(capsys, ["repose", str(smoke_run[0]), *args, "--json", str(out)])
    assert message in err and not out.exists()


def test_cli_refuses_bad_files(smoke_run, tmp_path, capsys):
    out = tmp_path / "r.json"
    assert "no such run file or directory" in _one_line_error(
        capsys, ["repose", str(tmp_path / "nothing.h5"), "--json", str(out)])
    (tmp_path / "text.h5").write_text("not a run\n")
    assert "text.h5: not a readable HDF5 file" in _one_line_error(
        capsys, ["repose", str(tmp_path / "text.h5"), "--json", str(out)])
    (tmp_path / "run.h5.part").write_bytes(b"")
    assert "an incomplete run" in _one_line_error(capsys, ["repose", str(tmp_path / "run.h5")])
    empty = tmp_path / "empty"
    empty.mkdir()
    assert "no run_*.h5 files" in _one_line_error(capsys, ["repose", str(empty)])
    assert "--json" in _one_line_error(capsys, ["repose", str(smoke_run[0]), "--json", str(empty)])
    assert not out.exists()
