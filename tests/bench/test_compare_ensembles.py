"""perf.compare_ensembles: the onset and quiet network of ensembles that differ in one setting."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from benchmarks import compare_ensembles as ce


def test_config_diff_names_nested_keys():
    ref = {"solver": {"dt": 0.01, "tol": 1e-6}, "scene": {"n": 1000}}
    cfg = {"solver": {"dt": 0.02, "tol": 1e-6}, "scene": {"n": 1000, "mu": 0.5}}
    assert ce.config_diff(ref, cfg) == {"solver.dt": (0.01, 0.02), "scene.mu": (None, 0.5)}
    assert ce.config_diff(ref, ref) == {}


def test_welch_shift_and_p():
    """Known answers: equal samples give shift 0, p 1; two samples 3 sd apart, p < 1e-3 (scipy's
    Welch test); runs without onset (NaN) are left out, and fewer than two values give NaN."""
    a = np.array([9.0, 10.0, 11.0, 10.0, 9.5, 10.5])
    assert ce.welch(a, a[::-1]) == (0.0, 1.0)
    shift, p = ce.welch(a, a + 3.0)
    assert shift == pytest.approx(3.0) and p < 1e-3
    shift, p = ce.welch(a, np.r_[a + 0.1, np.nan])
    assert shift == pytest.approx(0.1) and 0.5 < p <= 1.0
    assert np.isnan(ce.welch(a, [np.nan, 10.0])[1])


def test_compare_two_copies_of_the_smoke_run(smoke_run, tmp_path, capsys):
    """Two directories holding the same run: the same numbers, no configuration difference, no
    shift; the onset is the one the figure code finds (``ensemble_data.first_onsets``)."""
    from tiltpile.analysis.ensemble_data import first_onsets, load_ensemble

    path, _ = smoke_run
    dirs = []
    for name in ("a", "b"):
        d = tmp_path / name
        d.mkdir()
        shutil.copy(path, d / path.name)
        dirs.append(d)
    rows = ce.main([str(d) for d in dirs])
    out = capsys.readouterr().out
    assert "reference" in out and "the reference's configuration" in out
    ref, again = rows
    ens = load_ensemble(dirs[0])
    assert np.array_equal(ref["theta_m"], first_onsets(ens.frames, ens.seeds), equal_nan=True)
    assert ref["n_onset"] == 1 and 5.0 < ref["theta_m_mean"] < 30.0 and np.isnan(ref["theta_m_sem"])
    assert again["diff"] == {} and again["theta_m_mean"] == ref["theta_m_mean"]
    assert again["z_quiet_mean"] == ref["z_quiet_mean"] and again["n_m_quiet_mean"] == ref["n_m_quiet_mean"]
    assert np.isnan(again["theta_m_p"]) and np.isnan(again["z_quiet_p"])  # one run each: no test
    assert 2.5 < ref["z_quiet_mean"] < 4.0 and 0.0 <= ref["n_m_quiet_mean"] <= 1.0
