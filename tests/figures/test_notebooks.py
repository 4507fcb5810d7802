"""Every figure notebook runs through papermill on a tiny smoke ensemble, and its numbers are locked.

The session fixture (``smoke_ensemble``, tests/conftest.py) simulates three smoke piles
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
no stored outputs, and each exercised here. Every analysis parameter is a parameter of every
figure (tiltpile.figures.build) and of the preparation study's notebook at its default value, and
reaches the figure: a changed one is computed with and recorded in the JSON.
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
SEEDS = [1, 2, 3]   # the seeds of the session's smoke ensemble (tests/conftest.py)
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
    assert doc["analysis"] == {"cutoff": 0.02, "lost_gap": None}   # the defaults: only these named
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


# figures beyond the paper, numbered after its figures (their notebooks follow the same contract)
BEYOND_PAPER = ("fig7_rigidity",)


def test_every_figure_has_one_notebook():
    n = _paper_figures()
    assert n == 6
    for k in range(1, n + 1):
        mine = [p for p in NOTEBOOKS if p.name.startswith(f"fig{k}_")]
        assert len(mine) == 1, f"figure {k} of the paper needs exactly one notebook, found {mine}"
    extra = sorted(p.stem for p in NOTEBOOKS if int(re.match(r"fig(\d+)_", p.name).group(1)) > n)
    assert extra == sorted(BEYOND_PAPER), f"notebooks without a figure of the paper: {extra}"


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
    # the parameters cell restates no default: the figure's own are its module's (build.py)
    assert names == {"data_dir", "preset", "figures_dir", "overrides"}, \
        f"{nb.name}: the parameters cell holds the data, preset, output and overrides only"
    code = "\n".join(c.source for c in book.cells if c.cell_type == "code")
    assert f'build.given("fig{k}", overrides, globals())' in code and f'build.save("fig{k}"' in code
    from tiltpile.figures import build
    assert build.STEMS[f"fig{k}"] == nb.stem, f"{nb.name} must save its figure as {nb.stem}"


# -- the analysis parameters reach the figures -------------------------------------------------------

def _parameters(nb: Path) -> dict:
    """{name: value} of a notebook's parameters cell (literal values)."""
    import ast

    book = nbformat.read(nb, as_version=4)
    cell = next(c for c in book.cells if "parameters" in c.get("metadata", {}).get("tags", []))
    out = {}
    for node in ast.parse(cell.source).body:
        assert isinstance(node, ast.Assign) and len(node.targets) == 1, f"{nb.name}: {ast.unparse(node)}"
        out[node.targets[0].id] = ast.literal_eval(node.value)
    return out




def test_only_the_declared_figures_read_the_per_run_table():
    from tiltpile.analysis import observables

    src = ROOT / "src" / "tiltpile" / "figures"
    # analysis.run_table by name (preparation.per_run_table, its per-run numbers of a study, is
    # another function)
    readers = {p.stem for p in src.glob("*.py")
               if any(k in p.read_text() for k in observables.RUN_TABLE_PARAMS)
               or re.search(r"\brun_table\b", p.read_text())}
    assert readers == {"fig2", "preparation"}


def test_every_analysis_parameter_is_a_figure_parameter():
    """Every figure takes every analysis parameter of the tables (and Fig. 2 the per-run
    table's) at the analysis default, and its own at its module's ``compute`` defaults; a name
    given twice is the analysis' (build.py)."""
    import inspect

    from tiltpile.analysis import DEFAULT_PARAMS
    from tiltpile.figures import build

    from tiltpile.analysis.observables import RUN_TABLE_PARAMS

    for name, mod in build.MODULES.items():
        params = build.parameters(name)
        # the per-run table's parameters are Fig. 2's only: NB="-p slide_ke ..." changes no other
        runs = name == "fig2"
        want = {k: v for k, v in DEFAULT_PARAMS.items() if runs or k not in RUN_TABLE_PARAMS}
        assert {k: params[k] for k in want} == want and (runs or not set(RUN_TABLE_PARAMS) & set(params))
        sig = inspect.signature(mod.compute).parameters
        for k, v in build.figure_parameters(name).items():
            assert sig[k].default == v and k not in DEFAULT_PARAMS
    with pytest.raises(ValueError, match="epss: not a parameter of fig4"):
        build.given("fig4", {"epss": 0.01})
    with pytest.raises(ValueError, match="cutoff must be in"):
        build.given("fig4", {"cutoff": 2.0})
    # what papermill injects into a notebook's globals counts, an explicit override wins
    got = build.given("fig4", {"z_bin": 0.2}, {"eps": 0.01, "z_bin": 0.5, "data_dir": "x"})
    assert (got["eps"], got["z_bin"], "data_dir" in got) == (0.01, 0.2, False)


def test_the_preparation_notebook_passes_every_analysis_parameter():
    """The preparation study's notebook (not a figure of build.py) declares every analysis
    parameter at its default and passes each on."""
    from tiltpile.analysis import DEFAULT_PARAMS

    import papermill

    nb = NOTEBOOK_DIR / "preparation.ipynb"
    params = _parameters(nb)
    assert list(papermill.inspect_notebook(str(nb))) == list(params), \
        f"{nb.name}: papermill does not read every parameter (one '=' per line, comments included)"
    for k in DEFAULT_PARAMS:
        assert params[k] == DEFAULT_PARAMS[k] and type(params[k]) is type(DEFAULT_PARAMS[k]), \
            f"{nb.name}: {k} = {params[k]!r}, the analysis default is {DEFAULT_PARAMS[k]!r}"
    book = nbformat.read(nb, as_version=4)
    code = "\n".join(c.source for c in book.cells
                     if c.cell_type == "code" and "parameters" not in c.get("metadata", {}).get("tags", []))
    for k in sorted(DEFAULT_PARAMS):
        assert re.search(rf"\b{k}={k}\b", code), f"{nb.name} declares {k} but does not pass it on"


@pytest.mark.slow
def test_a_changed_analysis_parameter_reaches_the_figure(smoke_ensemble, tmp_path):
    """-p eps 0.01: the figure is computed with it (its numbers differ from the defaults') and
    its JSON says so."""
    import papermill as pm

    from tiltpile.figures import data, fig4, style

    nb = NOTEBOOK_DIR / "fig4_cluster_isostaticity.ipynb"
    pm.execute_notebook(str(nb), str(tmp_path / "executed.ipynb"), kernel_name="tiltpile",
                        cwd=str(ROOT), progress_bar=False, log_output=False,
                        parameters={"data_dir": str(smoke_ensemble), "preset": "smoke",
                                    "figures_dir": str(tmp_path), "eps": 0.01})
    doc = json.loads((tmp_path / f"{nb.stem}.json").read_text())
    assert doc["analysis"] == {"cutoff": 0.02, "eps": 0.01, "lost_gap": None}
    with_eps = flatten(doc["numbers"])
    assert with_eps == flatten(style.jsonable(fig4.compute(data.load(smoke_ensemble, "smoke",
                                                                     eps=0.01))[0]))
    default = flatten(style.jsonable(fig4.compute(data.load(smoke_ensemble, "smoke"))[0]))
    assert with_eps.keys() == default.keys() and with_eps != default
