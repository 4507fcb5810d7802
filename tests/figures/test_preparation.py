"""The preparation study: compute() on two tiny simulated ensembles, fresh and prepared
(pretilt [5, -5, 0] deg), against the analysis functions run by run; labels from the run files;
the notebook writes its JSON; bad input refused with one message. About 30 s on a loaded core.
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from tiltpile.analysis import first_slide, run_table  # noqa: E402
from tiltpile.analysis import stats as st  # noqa: E402
from tiltpile.analysis.ensemble_data import first_onsets  # noqa: E402
from tiltpile.figures import fig2, preparation  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TINY = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=25.0"]
PRETILT = [5.0, -5.0, 0.0]
SEEDS = [1, 2]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """Two seeds each of a 60-grain smoke pile, fresh and prepared, with their observables."""
    from tiltpile import config
    from tiltpile.analysis import compute_observables
    from tiltpile.runner import simulate

    root = tmp_path_factory.mktemp("prep")
    dirs = {}
    for name, extra in (("fresh", []), ("prep", [f"protocol.pretilt_deg={PRETILT}"])):
        cfg = config.load("smoke", overrides=TINY + [x.replace(" ", "") for x in extra])
        for s in SEEDS:
            simulate(cfg, s, root / name / f"run_{s:04d}.h5", progress=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")       # 60 grains: the cutoff's resolution warning
            compute_observables(root / name, workers=1, progress=False)
        dirs[name] = root / name
    return dirs


@pytest.fixture(scope="module")
def study(tiny):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ens, labels, hist = preparation.load([tiny["fresh"], tiny["prep"]], [])
        numbers, d = preparation.compute(ens, labels, hist)
    return ens, labels, hist, numbers, d


# ---------------------------------------------------------------------------------------------
# pure pieces with known answers


def test_history_labels():
    assert preparation.history_label([]) == "fresh"
    assert preparation.history_label([10.0, -10.0, 0.0]) == "±10° once"
    assert preparation.history_label([15, -15, 15, -15, 0]) == "±15° twice"
    assert preparation.history_label([5, -5] * 3 + [0]) == "±5° 3 times"
    assert preparation.history_label([-7.5, 7.5, 0]) == "∓7.5° once"
    assert preparation.history_label([12.0, 0.0]) == "12° once"
    assert preparation.history_label([10.0, -5.0, 0.0]) == "pretilt 10/-5/0°"
    # Deboeuf's history, as protocol.cycles / theta_rev_deg write it
    from tiltpile.config import deboeuf_history
    assert preparation.history_label(deboeuf_history(2, 16.0)) == "±16° 2 cycles"
    assert preparation.history_label(deboeuf_history(1, 10.0)) == "±10° 1 cycle"
    assert preparation.history_label(deboeuf_history(0, 10.0)) == "10° once"
    # a history at its own rate says so
    assert preparation.rate_suffix({"protocol": {"tilt_per_step_deg": 0.002,
                                                 "pretilt_per_step_deg": 0.02}}) == " at 10x rate"
    assert preparation.rate_suffix({"protocol": {"tilt_per_step_deg": 0.002}}) == ""


# ---------------------------------------------------------------------------------------------
# the study on simulated ensembles


def test_labels_and_histories_come_from_the_run_files(study):
    ens, labels, hist, numbers, _ = study
    assert labels == ["fresh", "±5° once"]
    assert hist == [[], PRETILT]
    assert list(numbers["ensembles"]) == labels and numbers["reference"] == "fresh"
    assert numbers["ensembles"]["±5° once"]["pretilt_deg"] == PRETILT
    # only the preparation differs between the two configurations
    assert numbers["config_differences"] == []
    assert numbers["below_deg"] == 5.0
    assert all(numbers["ensembles"][lab]["seeds"] == SEEDS for lab in labels)


def test_numbers_equal_the_analysis_run_by_run(study):
    ens, labels, _, numbers, d = study
    for e, lab in zip(ens, labels):
        out = numbers["ensembles"][lab]
        f = e.frames.sort_values(["run", "frame"], kind="stable")
        # the slide as Fig. 2 detects it: the ensemble's KE threshold, the analysis' least span
        thr = st.ke_threshold(f, "ke_trans")[0]["threshold"]
        assert out["slide_ke"] == pytest.approx(thr)
        rt = run_table(f, slide_ke=thr, slide_sustain_deg=out["slide_sustain_deg"]).set_index("run")
        pr = out["per_run"]
        np.testing.assert_array_equal(pr["theta_first_onset"], first_onsets(f, e.seeds))
        np.testing.assert_array_equal(pr["theta_first_onset"],
                                      rt.loc[e.seeds, "theta_first_onset"].to_numpy())
        np.testing.assert_array_equal(pr["theta_first_slide"],
                                      rt.loc[e.seeds, "theta_first_slide"].to_numpy())
        for k, s in enumerate(e.seeds):
            g = f[f["run"] == s]
            th = g["theta_deg"].to_numpy(float)
            sl = first_slide(th, g["ke_trans"].to_numpy(float), thr, out["slide_sustain_deg"])
            assert pr["theta_first_slide"][k] == pytest.approx(sl, nan_ok=True)
            # and with the reference ensemble's threshold
            ref_ke = numbers["ensembles"]["fresh"]["slide_ke"]
            assert numbers["slide_ke_reference"] == ref_ke
            sl_ref = first_slide(th, g["ke_trans"].to_numpy(float), ref_ke,
                                 out["slide_sustain_deg"])
            assert pr["theta_first_slide_ref_ke"][k] == pytest.approx(sl_ref, nan_ok=True)
            assert pr["n_precursors_ref_ke"][k] == preparation.precursor_count(
                th, g["onset"].to_numpy(bool), g["avalanching"].to_numpy(bool), sl_ref)
            quiet = ~g["avalanching"].to_numpy(bool)
            assert pr["z_quiet"][k] == pytest.approx(g["z"][quiet].mean())
            assert pr["n_m_quiet"][k] == pytest.approx(g["n_m"][quiet].mean())
            # precursors: onsets whose avalanching stretch has ended before the slide's frame
            on = np.flatnonzero(g["onset"].to_numpy(bool))
            av = g["avalanching"].to_numpy(bool)
            n = 0
            for i in on:
                j = i
                while j + 1 < av.size and av[j + 1]:
                    j += 1
                n += bool(not np.isfinite(sl) or th[j] < sl)
            assert pr["n_precursors"][k] == n
            assert pr["n_precursors"][k] <= pr["n_onsets"][k] == on.size
            # onsets below the study's largest pretilt angle (5 deg)
            assert pr["n_onsets_below"][k] == (th[on] < 5.0).sum()
            # the memory measures: against the ensemble's own largest history angle (NaN fresh)
            rev = 5.0 if lab != "fresh" else np.nan
            assert out["theta_rev_deg"] == pytest.approx(rev, nan_ok=True)
            lf = np.nan_to_num(g["lost_fraction"].to_numpy(float))
            first = th[lf > preparation.CHANGE_CUTOFF]
            assert pr["theta_first_change"][k] == pytest.approx(first[0] if first.size else np.nan,
                                                                nan_ok=True)
            if lab == "fresh":
                assert np.isnan(pr["n_onsets_below_rev"][k]) and np.isnan(pr["onset_over_rev"][k])
            else:
                assert pr["n_onsets_below_rev"][k] == (th[on] < 5.0).sum()
                assert pr["onset_over_rev"][k] == pytest.approx(pr["theta_first_onset"][k] / 5.0,
                                                                nan_ok=True)
            # the structure at frame 0 is that of the run file's first frame
            from tiltpile.analysis.structure import bulk_window, packing_fraction
            from tiltpile.store import open_run
            with open_run(e.run_path(s)) as r:
                pos = r.position(0)
                win = bulk_window(pos, r.radius, r.fixed, r.box_length,
                                  margin=preparation.BULK_MARGIN)
                assert pr["phi_start"][k] == packing_fraction(pos, r.radius, win)
                from tiltpile.analysis.structure import surface_tilt_deg
                assert pr["surface_tilt_start"][k] == pytest.approx(
                    surface_tilt_deg(pos, r.radius, r.fixed, r.box_length), nan_ok=True)
            assert 0.5 < pr["phi_start"][k] < 0.91  # below the densest packing of disks
            assert 0.0 <= pr["fabric_start"][k] <= 2.0
            assert -90.0 < pr["fabric_major_start"][k] <= 90.0
        quiet_past = np.nan_to_num(np.asarray(pr["theta_first_onset"], float), nan=np.inf) >= 14.4
        assert out["n_runs_quiet_past"] == quiet_past.sum()
        # means and intervals over runs are the library's bootstrap of the per-run values
        for q in preparation.PER_RUN:
            ci = st.bootstrap_ci(pr[q])
            assert out[f"{q}_mean"] == pytest.approx(ci["estimate"], nan_ok=True)
            assert out[f"{q}_ci_low"] == pytest.approx(ci["low"], nan_ok=True)
        # the Fig. 2b measure and the frames losing no contact are Fig. 2's
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            n2, _ = fig2.compute(e)
        assert out["lost_zero_fraction"] == pytest.approx(n2["lost_zero_fraction"])
        lf = f["lost_fraction"].to_numpy(float)
        lf = lf[np.isfinite(lf)]
        assert out["lost_zero_fraction"] == pytest.approx(np.mean(lf <= 0))
        assert out["lost_bimodality"]["n"] == n2["lost_bimodality"]["n"]
        assert out["lost_bimodality"]["delta_bic"] == pytest.approx(
            n2["lost_bimodality"]["delta_bic"], nan_ok=True)
        assert out["theta_m_mean_fig2"] == pytest.approx(out["theta_first_onset_mean"])
    diff = numbers["differences"]["±5° once"]["z_quiet"]
    assert diff["estimate"] == pytest.approx(numbers["ensembles"]["±5° once"]["z_quiet_mean"]
                                             - numbers["ensembles"]["fresh"]["z_quiet_mean"])
    fig = preparation.plot(d, numbers)
    assert len(fig.axes) == 8
    plt.close(fig)


def test_the_notebook_writes_the_json(tiny, tmp_path):
    import papermill as pm
    os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".venv" / "numba-cache"))
    pm.execute_notebook(str(ROOT / "notebooks" / "preparation.ipynb"), str(tmp_path / "run.ipynb"),
                        kernel_name="tiltpile", cwd=str(ROOT), progress_bar=False,
                        parameters={"data_dirs": [str(tiny["fresh"]), str(tiny["prep"])],
                                    "labels": ["fresh piles", "prepared"],
                                    "figures_dir": str(tmp_path)})
    for ext in ("png", "pdf", "json"):
        assert (tmp_path / f"preparation.{ext}").stat().st_size > 0
    doc = json.loads((tmp_path / "preparation.json").read_text())
    assert doc["figure"] == "preparation"
    meta = doc["ensembles"]
    assert [m["label"] for m in meta] == ["fresh piles", "prepared"]
    assert [m["pretilt_deg"] for m in meta] == [[], PRETILT]
    assert all(m["seeds"] == SEEDS and m["n_runs"] == 2 and len(m["config_hash"]) == 12
               for m in meta)
    assert meta[0]["config_hash"] != meta[1]["config_hash"]
    assert list(doc["numbers"]["ensembles"]) == ["fresh piles", "prepared"]
    assert doc["numbers"]["ensembles"]["prepared"]["n_runs"] == 2


def test_make_preparation_and_zcount_end_to_end(tiny, tmp_path):
    """docs/cli.md, "The preparation study, end to end", on existing ensembles (PREP_DIRS): the
    study's figure, then <z>; a second make does nothing, a changed run file redoes both."""
    import subprocess

    figs, executed = tmp_path / "figs", tmp_path / "executed"
    args = ["make", "-o", ".venv/.tiltpile-installed", f"PREP_DIRS={tiny['fresh']} {tiny['prep']}",
            "PREP_LABELS=fresh piles|prepared", f"PREP_FIGURES={figs}", f"PREP_EXECUTED={executed}"]

    def make(*goals):
        r = subprocess.run([*args, *goals], cwd=ROOT, capture_output=True, text=True, timeout=900,
                           env=dict(os.environ, NUMBA_CACHE_DIR=str(ROOT / ".venv" / "numba-cache")))
        assert r.returncode == 0, r.stdout + r.stderr
        return r.stdout

    out = make("preparation", "zcount")
    assert "papermill notebooks/preparation.ipynb" in out and "tiltpile zcount" in out
    doc = json.loads((figs / "preparation.json").read_text())
    assert list(doc["numbers"]["ensembles"]) == ["fresh piles", "prepared"]
    assert (figs / "zcount.json").stat().st_size > 0
    out = make("preparation", "zcount")
    assert "papermill" not in out and "tiltpile zcount" not in out
    run = tiny["prep"] / "run_0001.h5"
    st = run.stat()
    os.utime(run, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
    out = make("preparation", "zcount")
    assert "papermill notebooks/preparation.ipynb" in out and "tiltpile zcount" in out


# ---------------------------------------------------------------------------------------------
# bad input


def test_bad_input_is_refused_with_one_message(tiny, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match=r"^preparation study: .*empty holds no run_\*\.h5"):
        preparation.load([tiny["fresh"], empty], [])
    with pytest.raises(ValueError, match="3 labels for 2 ensemble directories"):
        preparation.load([tiny["fresh"], tiny["prep"]], ["a", "b", "c"])
    with pytest.raises(ValueError, match="labels repeat"):
        preparation.load([tiny["fresh"], tiny["prep"]], ["a", "a"])
    with pytest.raises(ValueError, match="no ensemble directory"):
        preparation.load([], [])
    # every problem in the one message
    with pytest.raises(ValueError) as info:
        preparation.load([empty, tmp_path / "missing"], ["x"])
    msg = str(info.value)
    assert "holds no run" in msg and "is not a directory" in msg and "1 labels for 2" in msg
    # an ensemble whose runs were prepared differently
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    (mixed / "run_0001.h5").symlink_to(tiny["fresh"] / "run_0001.h5")
    (mixed / "run_0002.h5").symlink_to(tiny["prep"] / "run_0002.h5")
    with pytest.raises(ValueError, match="different preparation histories"):
        preparation.preparation_history(mixed)
    with pytest.raises(ValueError, match="2 labels for 1 ensembles"):
        preparation.compute([object()], ["a", "b"])


def test_repose_angles_come_from_the_ensembles_repose_json(tiny, tmp_path):
    """DIR/repose.json (``tiltpile repose DIR --json DIR/repose.json``) reaches the study's
    numbers per seed; a file measured on other seeds is refused."""
    import shutil
    d = tmp_path / "fresh"
    shutil.copytree(tiny["fresh"], d)
    summ = {"runs": 2, "outcomes": {"stopped": 2}, "stop_deg": {"estimate": 15.0, "low": 14.0,
            "high": 16.0, "n": 2}, "slide_deg": {"estimate": 20.0, "low": 19.0, "high": 21.0, "n": 2}}
    doc = {"format": 1, "params": {}, "summary": summ,
           "runs": [{"seed": 2, "stop_deg": 16.0, "slide_deg": 21.0},
                    {"seed": 1, "stop_deg": 14.0, "slide_deg": 19.0}]}
    (d / preparation.REPOSE_FILE).write_text(json.dumps(doc))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ens, labels, hist = preparation.load([d], [])
    rep = preparation.repose_numbers(ens[0])
    assert rep["stop_deg_per_run"] == [14.0, 16.0] and rep["slide_deg_per_run"] == [19.0, 21.0]
    assert rep["stop_deg"]["estimate"] == 15.0
    doc["runs"][0]["seed"] = 7
    (d / preparation.REPOSE_FILE).write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="seeds"):
        preparation.repose_numbers(ens[0])


def test_a_study_of_records_is_the_study_of_their_run_files(tiny, study, tmp_path):
    """Ensembles given by their records (the paper scale's are committed so): the same labels,
    histories and numbers as from the run files, except the frame-0 structure, which needs the
    positions and is NaN; the JSON says which ensembles came from records, the report says what
    they cannot give."""
    from tiltpile.figures.records import write_records
    from tiltpile.report.studies import render_preparation

    dirs = []
    for name in ("fresh", "prep"):
        write_records(tiny[name], tmp_path / name, workers=1, progress=False)
        dirs.append(tmp_path / name)
    assert not list((tmp_path / "fresh").glob("run_*.h5"))
    _, labels0, hist0, numbers0, _ = study
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ens, labels, hist = preparation.load(dirs, [])
        numbers, _ = preparation.compute(ens, labels, hist)
    assert (labels, hist) == (labels0, hist0) and all(e.records for e in ens)

    def without_structure(x, path=""):
        if isinstance(x, dict):
            return {k: without_structure(v, f"{path}.{k}") for k, v in x.items()
                    if not k.startswith(preparation.STRUCTURE)}
        return x

    assert json.dumps(without_structure(numbers), sort_keys=True, default=str) == json.dumps(
        without_structure(numbers0), sort_keys=True, default=str)
    for lab in labels:
        e = numbers["ensembles"][lab]
        assert all(np.isnan(e["per_run"][c]).all() and np.isnan(e[f"{c}_mean"])
                   for c in preparation.STRUCTURE)
        assert np.isfinite(numbers0["ensembles"][lab]["phi_start_mean"])
    meta = preparation.meta(ens, labels, hist)
    assert [m["from_records"] for m in meta["ensembles"]] == [True, True]
    (tmp_path / "preparation.json").write_text(json.dumps(
        {"figure": "preparation", **meta, "numbers": numbers}, default=float))
    text = "\n".join(render_preparation(tmp_path))
    assert f"Read from their records (no run files): {labels[0]}, {labels[1]};" in text
    # a directory with neither is refused, saying what it lacks
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match=r"empty holds no run_\*\.h5 files nor records run_\*\.npz"):
        preparation.check_inputs([dirs[0], empty])
