"""Every figure notebook runs through papermill on a tiny smoke ensemble, and its numbers are locked.

The session fixture (``smoke_ensemble``, tests/figures/conftest.py) simulates three smoke piles
(seeds 1-3) through the ensemble runner, as `make figures PRESET=smoke` would. Each notebook then runs on them exactly as `make figures` runs
it (same kernel, same parameters, working directory the repository) and writes its PDF, PNG and
JSON to a temporary directory. The JSON numbers are compared with the baselines in
``tests/figures/test_notebooks/`` (pytest-regressions; regenerate with ``--force-regen`` only for an
understood change, and say why in the commit message).

Tolerance: rtol 1e-7, atol 1e-10. The simulation is deterministic (same seed and config give
bit-identical run files on this machine; tests/workflow/test_run.py), so the only legitimate differences
are floating-point summation order in pandas/numpy reductions (~1e-15 relative) and the last digit
of text round trips. A change in the physics, the analysis or a figure's definition moves these
numbers by far more than 1e-7 and must show up here. Floating-point results are not expected to
carry over bit for bit to another CPU or another numba/LLVM version; regenerate the baselines
there.

The completeness test checks the contract of ``notebooks/``: one notebook per figure of the paper,
each with a header naming its figure and the paper, a ``parameters`` cell, the tiltpile kernel and
no stored outputs, and each exercised here.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import nbformat
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK_DIR = ROOT / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("fig*.ipynb"))
PAPER = next((ROOT / "paper").glob("*.tex"))
SEEDS = [1, 2, 3]   # the seeds of the session's smoke ensemble (tests/figures/conftest.py)
RTOL, ATOL = 1e-7, 1e-10


def flatten(numbers, prefix: str = "") -> dict:
    """{"a": {"b": [1, 2]}} -> {"a.b[0]": 1, "a.b[1]": 2}; None (NaN in the JSON) stays None."""
    out = {}
    if isinstance(numbers, dict):
        for k, v in numbers.items():
            out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(numbers, list):
        for i, v in enumerate(numbers):
            out.update(flatten(v, f"{prefix}[{i}]"))
    else:
        out[prefix] = numbers
    return out


def execute(nb: Path, data_dir: Path, figures_dir: Path) -> Path:
    import papermill as pm

    out = figures_dir / f"executed_{nb.name}"
    pm.execute_notebook(str(nb), str(out), kernel_name="tiltpile", cwd=str(ROOT),
                        progress_bar=False, log_output=False,
                        parameters={"data_dir": str(data_dir), "preset": "smoke",
                                    "figures_dir": str(figures_dir)})
    return out


@pytest.mark.slow
@pytest.mark.parametrize("nb", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_figure_notebook(nb, smoke_ensemble, tmp_path, num_regression, data_regression):
    executed = execute(nb, smoke_ensemble, tmp_path)
    stem = nb.stem
    for ext in ("pdf", "png", "json"):
        assert (tmp_path / f"{stem}.{ext}").stat().st_size > 0, f"{stem}.{ext} not written"

    # notebook hygiene: nothing on stderr, no error outputs
    run = nbformat.read(executed, as_version=4)
    for cell in run.cells:
        for o in cell.get("outputs", []):
            assert not (o.get("output_type") == "stream" and o.get("name") == "stderr"), \
                f"{stem} wrote to stderr: {o.get('text', '')[:300]}"
            assert o.get("output_type") != "error"

    doc = json.loads((tmp_path / f"{stem}.json").read_text())
    assert doc["figure"] == stem
    assert doc["preset"] == "smoke" and doc["n_runs"] == len(SEEDS) and doc["seeds"] == SEEDS
    flat = flatten(doc["numbers"])
    assert flat, f"{stem} reports no numbers"
    numeric = {k: v for k, v in flat.items()
               if v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))}
    other = {k: v for k, v in flat.items() if k not in numeric}
    # NaN is a legitimate value (a refused fit on 3 small runs); lock it as NaN
    num_regression.check({k: np.array([np.nan if v is None else float(v)]) for k, v in numeric.items()},
                         default_tolerance=dict(rtol=RTOL, atol=ATOL))
    if other:
        data_regression.check(other)


def _paper_figures() -> int:
    return len(re.findall(r"\\begin\{figure\}", PAPER.read_text()))


def test_every_figure_has_one_notebook():
    n = _paper_figures()
    assert n == 6
    for k in range(1, n + 1):
        mine = [p for p in NOTEBOOKS if p.name.startswith(f"fig{k}_")]
        assert len(mine) == 1, f"figure {k} of the paper needs exactly one notebook, found {mine}"
    assert len(NOTEBOOKS) == n, f"notebooks without a figure of the paper: {NOTEBOOKS}"


@pytest.mark.parametrize("nb", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_contract(nb):
    book = nbformat.read(nb, as_version=4)
    k = int(re.match(r"fig(\d+)_", nb.name).group(1))
    head = book.cells[0]
    assert head.cell_type == "markdown" and head.source.startswith(f"# Fig. {k} "), \
        f"{nb.name}: the first cell must be a markdown header '# Fig. {k} ...'"
    assert "Henkes" in head.source and "Local Coulomb versus Global Failure" in head.source
    params = [c for c in book.cells if "parameters" in c.get("metadata", {}).get("tags", [])]
    assert len(params) == 1 and book.cells.index(params[0]) == 1, \
        f"{nb.name}: the second cell, and only it, is tagged 'parameters'"
    names = set(re.findall(r"^(\w+)\s*=", params[0].source, flags=re.M))
    assert {"data_dir", "preset", "figures_dir"} <= names
    # the parameters cell holds inputs only: no imports, no calls
    inputs = "\n".join(line.split("#")[0] for line in params[0].source.splitlines())
    assert "import" not in inputs and not re.search(r"\w\s*\(", inputs), \
        f"{nb.name}: the parameters cell holds plain values; derived values go in the next cell"
    assert book.metadata["kernelspec"]["name"] == "tiltpile"
    assert all(not c.get("outputs") for c in book.cells if c.cell_type == "code"), \
        f"{nb.name}: store notebooks without outputs"
    code = "\n".join(c.source for c in book.cells if c.cell_type == "code")
    assert f"fig{k}" in code and "style.save(" in code
    assert nb.stem in code, f"{nb.name} must save its figure as {nb.stem}"
