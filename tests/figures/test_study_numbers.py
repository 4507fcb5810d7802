"""The parameter study's computation (tiltpile.figures.study): its plan helpers, and its numbers
against the figures whose numbers it takes, on the session's smoke ensemble."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tiltpile import config
from tiltpile.figures import study as st


def test_a_value_has_one_name_however_it_is_written():
    assert [st.value_label(v) for v in (0.2, 1.0, 5, True, "random")] == \
        ["0.2", "1.0", "5", "true", "random"]
    assert st.value_label(config.parse_override("scene.mu=1")["scene"]["mu"] * 1.0) == "1.0"


def test_the_history_option():
    assert st.parse_history(None) is None and st.parse_history("preset") is None
    assert st.parse_history("repose+1") == 1.0 and st.parse_history("repose+0.5") == 0.5
    for bad in ("repose", "repose-1", "repose+x", "16"):
        with pytest.raises(ValueError, match="repose"):
            st.parse_history(bad)


def test_the_amplitude_is_the_repose_angle_plus_d_rounded_to_the_degree():
    # the default ensemble's fresh piles: surface repose angle 14.7 deg -> the preset's 16 deg
    assert st.history_amplitude(14.704, 1.0) == 16.0
    assert st.history_amplitude(15.49, 1.0) == 16.0
    assert st.history_amplitude(15.5, 1.0) == 17.0
    assert st.history_amplitude(9.2, 0.5) == 10.0
    for bad in (float("nan"), None, -5.0, 95.0):
        with pytest.raises(ValueError):
            st.history_amplitude(bad, 1.0)


def test_the_history_overrides_make_the_fresh_and_the_cycled_piles():
    fresh = config.load("default", None, ["scene.mu=0.8", *st.history_overrides(None)])
    assert fresh.protocol.pretilt_deg == () and fresh.scene.mu == 0.8
    assert fresh.hash() == config.load("default-fresh", None, ["scene.mu=0.8"]).hash()
    cyc = config.load("default", None, ["scene.mu=0.5", *st.history_overrides(16.0)])
    assert cyc.hash() == config.load("default").hash()      # mu = 0.5 at 16 deg: the preset
    assert config.load("smoke", None, st.history_overrides(12.0)).protocol.pretilt_deg == \
        (12.0, -12.0, 12.0, -12.0, 12.0, 0.0)


def test_read_repose(tmp_path):
    doc = {"summary": {"outcomes": {"stopped": 1, "no stop": 1}}, "params": {},
           "runs": [{"seed": 3, "stop_deg": None, "surface_deg": None},
                    {"seed": 1, "stop_deg": 14.0, "surface_deg": 12.5}]}
    (tmp_path / "repose.json").write_text(json.dumps(doc))
    rep = st.read_repose(tmp_path / "repose.json")
    assert rep["seeds"] == [1, 3] and rep["stop_deg"][0] == 14.0 and math.isnan(rep["stop_deg"][1])
    assert st.repose_surface_mean(rep) == 12.5
    assert st.read_repose(tmp_path / "none.json") is None


@pytest.fixture(scope="module")
def smoke(smoke_ensemble):
    from tiltpile.figures.data import load
    return load(smoke_ensemble, "smoke")


def test_the_numbers_are_the_figures_numbers(smoke):
    from tiltpile.figures import fig2, fig3, fig7
    from tiltpile.analysis.mohr_coulomb import pooled_mean

    seeds = list(smoke.seeds)
    n3, _ = fig3.compute(smoke, snapshot=False)
    assert pooled_mean(st.quiet_orientations(smoke.clusters, seeds)) == \
        pytest.approx(n3["orientation_mean_deg"], rel=1e-12)
    n7, _ = fig7.compute(smoke, snapshot=False)
    rigid = st.quiet_near_means(smoke.frames, seeds, "rigid_fraction", st.RIGID_NEAR_DEG)
    assert np.nanmean(rigid) == pytest.approx(n7["rigid_fraction_near"]["estimate"], rel=1e-12)
    numbers, per_run = st.value_numbers(smoke, None)
    n2, _ = fig2.compute(smoke)
    assert per_run["theta_first_onset"] == pytest.approx(n2["theta_m_per_run"])
    assert numbers["z_quiet"]["estimate"] == pytest.approx(n2["z_quiet_run_mean"], rel=1e-12)
    assert numbers["quiet_below"]["estimate"] == pytest.approx(n2["quiet_below_run_mean"], rel=1e-12)
    assert list(numbers) == list(st.QUANTITIES)
    assert set(per_run) == set(st.QUANTITIES) - {"delta"}
    assert all(len(v) == len(seeds) for v in per_run.values())
    assert numbers["orientation"]["estimate"] == pytest.approx(n3["orientation_mean_deg"])
    assert math.isnan(numbers["repose_surface"]["estimate"])     # no repose.json given


def test_the_mohr_coulomb_test_comes_with_a_friction_study(smoke):
    entries = [{"value": mu, "label": st.value_label(mu), "ens": smoke, "repose": None,
                "repose_piles": "study", "theta_rev_deg": None} for mu in (0.2, 1.0)]
    out = st.compute("scene.mu", entries)
    mc = out["mohr_coulomb"]
    assert mc["predicted_deg"] == pytest.approx([50.655, 67.5], abs=0.001)
    # the same piles at both "frictions": the measured angle does not move
    assert mc["fit"]["slope"] == pytest.approx(0.0, abs=1e-9)
    assert st.compute("scene.polydispersity", entries)["mohr_coulomb"] is None
    from tiltpile.report.studies import render_study
    md = "\n".join(render_study({"numbers": out, "study": {"name": "friction", "preset": "smoke",
                                                          "runs": 3, "history": "preset"}}))
    assert "## Parameter study: scene.mu (friction)" in md
    assert "| 0.2 | 3 | preset |" in md and "| 1.0 | 3 | preset |" in md
    assert "**Mohr-Coulomb.**" in md and "mu = 0.2:" in md
    assert "measured against predicted 0.00" in md     # the same piles at both frictions
    assert mc["verdict"] in ("flat", "consistent")   # the interval: the 3 runs' scatter
