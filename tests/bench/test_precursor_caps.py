"""bench.precursor_caps: the same tilt from one state at several iteration caps."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tiltpile import config
from tiltpile.bench import precursor_caps
from tiltpile.runner import simulate


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("pc") / "run.h5"
    cfg = config.load("smoke", overrides=["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=3.0"])
    simulate(cfg, 1, path, progress=False)
    return path


def test_caps_that_are_not_reached_give_the_reference_and_a_starved_solver_does_not(run_file, tmp_path):
    out = tmp_path / "o.json"
    rows = precursor_caps.main([str(run_file), "--frames", "20", "--steps", "40", "--caps", "2", "100000",
                                "100001", "--json", str(out)])
    by_cap = {r["cap"]: r for r in rows}
    assert set(by_cap) == {2, 100000, 100001}
    ref = by_cap[100001]
    assert ref["dist_to_ref"] == 0.0 and ref["cap_fraction"] == 0.0
    # a cap no step reaches changes nothing, bit for bit
    same = by_cap[100000]
    assert same["dist_to_ref"] == 0.0 and same["ke_series"] == ref["ke_series"]
    starved = by_cap[2]
    assert starved["cap_fraction"] == 1.0 and starved["dist_to_ref"] > 0.0
    assert len(ref["ke_series"]) == 4 == len(ref["lost_series"])  # 40 steps, a frame every 10
    assert 0.0 <= ref["rest_fraction"] <= 1.0 and np.isfinite(ref["ke_mean"])
    assert json.loads(out.read_text())["rows"][0]["frame"] == 20


def test_bad_arguments_are_refused(run_file):
    with pytest.raises(SystemExit):
        precursor_caps.main([str(run_file), "--frames", "20", "--caps", "1000"])
