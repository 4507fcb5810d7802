"""bench.kill_resume: kill a run at chosen moments and ask what a rerun would find."""

from __future__ import annotations

import pytest

from tiltpile import store
from benchmarks import kill_resume as kr


def test_a_killed_run_resumes_and_one_left_alone_finishes(tmp_path):
    """Known answers. Killed after its checkpoint, wherever the kill lands (the next frame's
    write included: the frame log is only appended to), a run is resumable. A checkpoint it never
    reaches (more frames than the run has) lets it finish."""
    near = kr.study(3, min_frames=6, max_delay=0.0, progress=False)
    assert near == {"resumable": 3}, near
    assert kr.kill_once("smoke", kr.SMALL, 10_000, 0.0, tmp_path) == "finished"


def test_the_paper_write_pattern_is_resumable_when_killed_and_whole_when_not(tmp_path):
    assert kr.kill_once("", [], 1, 0.0, tmp_path / "a", pattern="paper", frames=4) == "resumable"
    kr.paper_pattern(tmp_path / "b" / "run_0000.h5", frames=3)
    assert store.verify(tmp_path / "b" / "run_0000.h5") == []
    with store.open_run(tmp_path / "b" / "run_0000.h5") as run:
        assert run.n_frames == 3 and run.radius.shape == (kr.PAPER["n"],)
        assert run.contacts(2)[0].shape == (kr.PAPER["contacts"], 2)


def test_bad_input_is_one_line(capsys):
    for argv, match in ((["0"], "N must be >= 1"), (["2", "--max-delay", "-1"], "--max-delay must be >= 0"),
                        (["2", "--set", "scene.n=-3"], "scene.n"), (["2", "--pattern", "x"], "--pattern"),
                        (["2", "--pattern", "paper", "--frames", "0"], "--frames must be >= 1")):
        with pytest.raises(SystemExit) as e:
            kr.main(argv)
        assert e.value.code == 2
        assert match in capsys.readouterr().err
    with pytest.raises(ValueError, match="N must be"):
        kr.study(0)
