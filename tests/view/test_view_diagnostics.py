"""notebooks/run_diagnostics.ipynb runs through papermill as `make figures` runs it, and its
series come from the run file and the observables."""

from __future__ import annotations

from pathlib import Path

import nbformat
import numpy as np

from tiltpile.analysis import run_observables
from tiltpile.store import open_run
from tiltpile.view import diagnostics

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK = ROOT / "notebooks" / "run_diagnostics.ipynb"


def test_run_series(tiny_run):
    s, facts = diagnostics.run_series(tiny_run)
    frames, _ = run_observables(tiny_run)
    with open_run(tiny_run) as run:
        assert len(s) == run.n_frames
        np.testing.assert_array_equal(s["cap_hits"], run.cap_hits)
        np.testing.assert_allclose(s["ke_per_grain"], run.ke / (~run.fixed).sum())
    np.testing.assert_array_equal(s["z"], frames["z"])
    assert facts["max_iter"] == 1000 and facts["cutoff"] == 0.02
    on = diagnostics.onset_summary(frames)
    assert on["theta_first_onset"].iloc[0] == frames.loc[frames["onset"], "theta_deg"].iloc[0]


def test_notebook_contract():
    book = nbformat.read(NOTEBOOK, as_version=4)
    assert book.cells[0].cell_type == "markdown" and book.cells[0].source.startswith("# Run diagnostics")
    assert "parameters" in book.cells[1].metadata.get("tags", [])
    assert {"run_file", "data_dir", "figures_dir"} <= set(
        line.split("=")[0].strip() for line in book.cells[1].source.splitlines() if "=" in line)
    assert all(not c.get("outputs") for c in book.cells if c.cell_type == "code")
    assert book.metadata["kernelspec"]["name"] == "tiltpile"


def test_notebook_runs_on_an_ensemble(tiny_ensemble, tmp_path):
    import shutil

    import papermill as pm

    ens = tmp_path / "ens"          # a copy: the notebook caches observables beside the runs
    shutil.copytree(tiny_ensemble, ens)
    out = tmp_path / "executed.ipynb"
    pm.execute_notebook(str(NOTEBOOK), str(out), kernel_name="tiltpile", cwd=str(ROOT),
                        progress_bar=False, log_output=False,
                        parameters={"data_dir": str(ens), "figures_dir": str(tmp_path)})
    assert (tmp_path / "run_diagnostics.png").stat().st_size > 10_000
    for cell in nbformat.read(out, as_version=4).cells:
        for o in cell.get("outputs", []):
            assert not (o.get("output_type") == "stream" and o.get("name") == "stderr"), o
            assert o.get("output_type") != "error"
