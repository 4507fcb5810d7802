"""Movies and stills of a run, read back by ffmpeg (imageio-ffmpeg) and Pillow."""

from __future__ import annotations

import imageio_ffmpeg
import numpy as np
import pytest
from PIL import Image

from tiltpile.cli import main
from tiltpile.view import movie


def test_mp4_read_back(tiny_run, tmp_path, capsys):
    out = tmp_path / "run.mp4"
    assert main(["movie", str(tiny_run), "--out", str(out), "--frames", "::3", "--width", "640",
                 "--forces", "--quiet"]) == 0
    n_frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert n_frames == 14                                   # frames 0, 3, ..., 39 of 41
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = next(reader)
    w, h = meta["size"]
    assert w == 640 and h % 2 == 0 and 200 < h < 640
    first = next(reader)
    img = np.frombuffer(first, np.uint8).reshape(h, w, 3)
    assert img.std() > 10                                   # a picture, not a blank frame
    reader.close()
    assert not list(tmp_path.glob(".*tmp*"))


@pytest.mark.parametrize("color", movie.COLORS_MODES)
def test_gif_in_every_color_mode(tiny_run, tmp_path, color):
    out = tmp_path / f"{color}.gif"
    r = movie.render(tiny_run, out, color=color, frames="30:36:2", width_px=400, progress=False)
    with Image.open(out) as im:
        assert im.n_frames == r["frames"] == 3
        assert im.size == (r["width"], r["height"]) and im.size[0] == 400


def test_png_still_and_refusals(tiny_run, tmp_path, capsys):
    out = tmp_path / "still.png"
    assert main(["movie", str(tiny_run), "--out", str(out), "--frames", "35", "--quiet"]) == 0
    with Image.open(out) as im:
        assert im.size[0] == 1280
    assert main(["movie", str(tiny_run), "--out", str(tmp_path / "x.png"), "--quiet"]) == 2
    assert "one frame" in capsys.readouterr().err
    assert main(["movie", str(tiny_run), "--out", str(tmp_path / "x.avi")]) == 2
    assert "NAME.mp4" in capsys.readouterr().err


def test_mp4_without_ffmpeg_falls_back_to_gif(tiny_run, tmp_path, monkeypatch):
    monkeypatch.setattr(movie, "ffmpeg_exe", lambda: None)
    with pytest.warns(RuntimeWarning, match="no ffmpeg"):
        r = movie.render(tiny_run, tmp_path / "run.mp4", frames="0:2", width_px=320, progress=False)
    assert r["path"].endswith("run.gif") and (tmp_path / "run.gif").exists()


def test_frame_size_does_not_depend_on_the_callers_style(tiny_run, tmp_path):
    import matplotlib

    with matplotlib.rc_context({"savefig.bbox": "tight", "font.size": 4}):
        r = movie.render(tiny_run, tmp_path / "s.png", frames="5", width_px=500, progress=False)
    with Image.open(tmp_path / "s.png") as im:
        assert im.size == (r["width"], r["height"]) and im.size[0] == 500
