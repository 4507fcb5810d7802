"""bench.kill_resume: kill a run at chosen moments and ask what a rerun would find."""

from __future__ import annotations

import pytest

from tiltpile.bench import kill_resume as kr


def test_a_run_killed_just_after_its_checkpoint_resumes_and_one_left_alone_finishes(tmp_path):
    """Known answers. Killed right after a checkpoint (between two flushes of its .part) a run is
    resumable: 2 of 3 at least (a kill that lands in the next write is the rare case this study
    counts). A checkpoint it never reaches (more frames than the run has) lets it finish."""
    near = kr.study(3, min_frames=6, max_delay=0.0, progress=False)
    assert sum(near.values()) == 3
    assert all(k in ("resumable", "finished") or k.startswith("refused: ") for k in near), near
    assert near["resumable"] >= 2, near
    assert kr.kill_once("smoke", kr.SMALL, 10_000, 0.0, tmp_path) == "finished"


def test_bad_input_is_one_line(capsys):
    for argv, match in ((["0"], "N must be >= 1"), (["2", "--max-delay", "-1"], "--max-delay must be >= 0"),
                        (["2", "--set", "scene.n=-3"], "scene.n")):
        with pytest.raises(SystemExit) as e:
            kr.main(argv)
        assert e.value.code == 2
        assert match in capsys.readouterr().err
    with pytest.raises(ValueError, match="N must be"):
        kr.study(0)
