"""notebooks/tutorial.ipynb runs through papermill as its header says, and what it computed holds.

The contract (fast): a header naming the paper, a ``parameters`` cell second and holding plain
values only, the tiltpile kernel, no stored outputs. The run (slow, as the figure notebooks'):
the notebook executed with papermill in a temporary directory (working directory the repository,
as `make figures` runs notebooks); its last cell writes ``tutorial.json`` beside the executed
notebook, whose numbers are checked against physics (z of a 2D frictional pile between 2 and
4.5, 0 <= n_m <= z / 2, clusters on the chosen frame) and against the analysis run again on the
run files the notebook wrote (the same z, n_m and clusters, bit for bit: the same code on the
same files). Lower friction must give the denser contact network (mean z over the quiet frames
at mu = 0.1 above that at mu = 0.5: 3.56 against 3.18 for seed 1, a margin far beyond one seed's
noise).
"""

from __future__ import annotations

import ast
import json
import math
import time
from pathlib import Path

import nbformat
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "notebooks" / "tutorial.ipynb"


def _parameters(book) -> dict:
    cell = book.cells[1]
    out = {}
    for node in ast.parse(cell.source).body:
        assert isinstance(node, ast.Assign) and len(node.targets) == 1, ast.unparse(node)
        out[node.targets[0].id] = ast.literal_eval(node.value)
    return out


def test_tutorial_contract():
    book = nbformat.read(NOTEBOOK, as_version=4)
    head = book.cells[0]
    assert head.cell_type == "markdown" and head.source.startswith("# Tutorial")
    assert "Henkes" in head.source and "Local Coulomb versus Global Failure" in head.source
    assert "papermill" in head.source and "notebooks/executed/" in head.source
    tagged = [c for c in book.cells if "parameters" in c.get("metadata", {}).get("tags", [])]
    assert tagged == [book.cells[1]], "the second cell, and only it, is tagged 'parameters'"
    params = _parameters(book)   # plain values only: literal_eval refuses calls and names
    assert {"seed", "preset", "theta_max_deg", "mu_compare", "out_dir"} <= set(params)
    assert params["preset"] == "smoke" and params["out_dir"].startswith("notebooks/executed/")
    assert book.metadata["kernelspec"]["name"] == "tiltpile"
    assert all(not c.get("outputs") and c.get("execution_count") is None
               for c in book.cells if c.cell_type == "code"), "store the notebook without outputs"
    # every step has its explanation: a markdown cell before each code cell after the setup
    kinds = [c.cell_type for c in book.cells]
    assert sum(k == "markdown" for k in kinds) >= 8


def _finite(xs) -> bool:
    return all(x is not None and math.isfinite(x) for x in xs)


@pytest.mark.slow
def test_tutorial_runs_and_its_numbers_hold(tmp_path):
    import papermill as pm

    from tiltpile.analysis import run_observables

    executed = tmp_path / "tutorial.ipynb"
    t0 = time.perf_counter()
    pm.execute_notebook(str(NOTEBOOK), str(executed), kernel_name="tiltpile", cwd=str(ROOT),
                        progress_bar=False, log_output=False,
                        parameters={"out_dir": str(tmp_path)})
    print(f"tutorial executed in {time.perf_counter() - t0:.0f} s")

    # notebook hygiene: no errors, nothing on stderr, every picture drawn
    run = nbformat.read(executed, as_version=4)
    images = 0
    for cell in run.cells:
        for o in cell.get("outputs", []):
            assert not (o.get("output_type") == "stream" and o.get("name") == "stderr"), \
                f"the tutorial wrote to stderr: {o.get('text', '')[:300]}"
            assert o.get("output_type") != "error"
            images += "image/png" in o.get("data", {})
    assert images >= 5

    doc = json.loads((tmp_path / "tutorial.json").read_text())
    assert doc["seed"] == 1 and doc["preset"] == "smoke"
    piles = doc["piles"]
    assert [p["mu"] for p in piles] == [0.5, 0.1]
    tables = {}
    for p in piles:
        z, n_m, theta = (np.array(p[c], dtype=float) for c in ("z", "n_m", "theta_deg"))
        assert len(z) == len(n_m) == len(theta) == len(p["avalanching"]) > 100
        assert _finite(p["z"]) and _finite(p["n_m"]) and _finite(p["dz_gen"])
        assert np.all((z > 2.0) & (z < 4.5)), (z.min(), z.max())
        assert np.all(n_m >= 0.0) and np.all(n_m <= z / 2.0)
        np.testing.assert_allclose(p["dz_gen"], z - 3.0 - n_m, atol=1e-12)
        assert theta[0] == 0.0 and np.all(np.diff(theta) > 0) and theta[-1] == pytest.approx(25.0)
        assert p["first_onset_deg"] is not None and 0.0 < p["first_onset_deg"] <= 25.0
        # the notebook's numbers are the analysis of the run file it wrote
        frames, clusters = tables[p["run_file"]] = run_observables(p["run_file"])
        np.testing.assert_array_equal(frames["z"].to_numpy(), z)
        np.testing.assert_array_equal(frames["n_m"].to_numpy(), n_m)
        assert frames["avalanching"].tolist() == p["avalanching"]

    quiet_z = [np.mean([z for z, a in zip(p["z"], p["avalanching"]) if not a]) for p in piles]
    assert quiet_z[1] > quiet_z[0] + 0.1, f"mean quiet z at mu 0.5, 0.1: {quiet_z}"

    cf = doc["cluster_frame"]
    assert cf["run_file"] == piles[0]["run_file"]
    assert cf["n_clusters"] > 0 and cf["n_clusters"] == len(cf["sizes"]) == len(cf["z"])
    assert cf["sizes"] == sorted(cf["sizes"], reverse=True) and min(cf["sizes"]) >= 1
    # each cluster holds a critical contact, and each critical contact lies in one cluster
    assert cf["n_critical_contacts"] >= cf["n_clusters"]
    assert all(n >= 0.5 for n in cf["n_m"])     # every cluster grain has a critical contact
    assert cf["theta_deg"] < piles[0]["first_onset_deg"]   # the quiet frame before the onset
    _, clusters = tables[cf["run_file"]]
    mine = clusters[clusters["frame"] == cf["frame"]]
    assert mine["size"].tolist() == cf["sizes"]
    np.testing.assert_allclose(mine["z"].to_numpy(), cf["z"], rtol=0, atol=1e-12)
