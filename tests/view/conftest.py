"""A tiny tilted pile (60 grains, 20 deg in a few seconds) with clusters, failing grains and
onsets, simulated once per session, and an ensemble directory of two of them."""

from __future__ import annotations

import json
import shutil

import pytest

from tiltpile import config
from tiltpile.runner import simulate

TINY = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=20.0",
        "protocol.tilt_per_step_deg=0.05", "protocol.frame_every=10"]


@pytest.fixture(scope="session")
def tiny_config():
    return config.load("smoke", None, TINY)


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory, tiny_config):
    """Path of the run file of seed 2 (41 frames, 0-20 deg; 2 onsets by the 2% criterion)."""
    out = tmp_path_factory.mktemp("tiny") / "run_0002.h5"
    simulate(tiny_config, 2, out, progress=False)
    return out


@pytest.fixture(scope="session")
def tiny_ensemble(tmp_path_factory, tiny_config, tiny_run):
    """An ensemble directory: seeds 2 and 3, a manifest, and an interrupted run_0004.h5.part."""
    d = tmp_path_factory.mktemp("ens")
    shutil.copy(tiny_run, d / "run_0002.h5")
    simulate(tiny_config, 3, d / "run_0003.h5", progress=False)
    (d / "run_0004.h5.part").write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(100))
    runs = {str(s): {"seed": s, "file": f"run_{s:04d}.h5", "status": "done"} for s in (2, 3)}
    runs["4"] = {"seed": 4, "file": "run_0004.h5", "status": "running"}
    (d / "ensemble.json").write_text(json.dumps({
        "format": "tiltpile-ensemble/1", "config_hash": tiny_config.hash(),
        "config": tiny_config.to_dict(), "seeds": [2, 3, 4], "runs": runs,
        "tiltpile_version": "test", "versions": {"numpy": "x"}, "invocations": []}))
    return d
