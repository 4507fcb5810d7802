"""The per-grain fields of tiltpile.view.fields agree with the analysis tables."""

from __future__ import annotations

import numpy as np
import pytest

from tiltpile.analysis import run_observables
from tiltpile.store import open_run
from tiltpile.view.fields import FrameFields, contact_segments, parse_frames


@pytest.mark.parametrize("text, expected", [
    (None, [0, 1, 2, 3, 4]), (":", [0, 1, 2, 3, 4]), ("1:4", [1, 2, 3]), ("::2", [0, 2, 4]),
    ("-2:", [3, 4]), ("3", [3]), ("-1", [4]),
])
def test_parse_frames(text, expected):
    assert parse_frames(text, 5) == expected


@pytest.mark.parametrize("text", ["a:b", "1:2:3:4", "::0", "4:1", "7", "1.5"])
def test_parse_frames_refuses(text):
    with pytest.raises(ValueError, match="--frames"):
        parse_frames(text, 5)


def test_contact_segments_end_on_the_walls():
    pos = np.array([[0.5, 0.5], [1.5, 0.6], [9.5, 2.0]])
    pair = np.array([[0, 1], [0, -1], [0, -2], [2, -3]])
    seg = contact_segments(pair, pos, 10.0)
    np.testing.assert_array_equal(seg[:, 0], pos[[0, 0, 0, 2]])
    np.testing.assert_array_equal(seg[:, 1], [[1.5, 0.6], [0.5, 0.0], [0.0, 0.5], [10.0, 2.0]])


def test_fields_match_the_observables(tiny_run):
    frames, clusters = run_observables(tiny_run)
    with open_run(tiny_run) as run:
        ff = FrameFields(run)
        prev = None
        for k in range(run.n_frames):
            f = ff.fields(k)
            row = frames.iloc[k]
            lab = f["cluster"]
            assert (lab >= 0).sum() == row["n_in_clusters"]
            assert (lab.max() + 1 if (lab >= 0).any() else 0) == row["n_clusters"]
            if k + 1 < run.n_frames:
                assert f["failing_next"].sum() == row["n_failing"]
                assert (f["failing_next"] & (lab >= 0)).sum() == row["n_failing_in_cluster"]
            else:
                assert not f["failing_next"].any()
            if prev is None:
                assert not f["failing"].any()
            else:
                np.testing.assert_array_equal(f["failing"], prev["failing_next"])
            assert f["active"].sum() == row["n_active"]
            assert f["mobilized"].sum() == row["n_mobilized"]
            j = f["pair"][:, 1]
            both = np.bincount(f["pair"][f["active"], 0], minlength=ff.n) + np.bincount(
                j[f["active"] & (j >= 0)], minlength=ff.n)
            np.testing.assert_array_equal(f["n_active"], both)
            assert not (f["failing"] & f["fixed"]).any()
            prev = f
    assert frames["n_failing"].max() > 0 and frames["n_in_clusters"].max() > 0
