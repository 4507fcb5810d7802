"""The build needs no list of dependencies: any edit under src/ rebuilds every figure, study and
report; a notebook rebuilds its own target (and the report after a figure); nothing else moves.

A scratch copy of the Makefile, ``src/``, ``notebooks/`` and up-to-date outputs (every figure's
JSON, the report, the preparation study and the <z> chart, each newer than its inputs) is asked
``make -n -W FILE`` (what would run if FILE were edited). The run stamps and the notebook
parameters (targets that are always checked) are held old with ``-o``, so that only the edited
file moves anything.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from importgraph import MODULES, imports_of
from makehelpers import MAKE_ENV

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"

FIG_NOTEBOOKS = sorted((ROOT / "notebooks").glob("fig*.ipynb"))
EVERYTHING = {nb.stem for nb in FIG_NOTEBOOKS} | {"preparation", "zcount", "report"}
SCALE_JSON = [Path("figures/smoke/fig2_avalanche_criterion.json"),
              Path("figures/default-fresh/fig2_avalanche_criterion.json"),
              Path("figures/default-fresh/fig6_cluster_stability.json"),
              Path("figures/paper/fig2_avalanche_criterion.json"),
              Path("figures/paper/fig5_cluster_sizes.json"),
              Path("figures/paper-fresh/fig1_isostaticity.json")]
STUDY_JSON = [Path("figures/preparation.json"), Path("figures/zcount.json")]


def test_figure_modules_import_no_other_figure_but_through_the_declared_ones():
    """Shared figure code lives in data.py, style.py and snapshot.py; the only figure module another
    imports is fig2 (the preparation study is Fig. 2's computation on several ensembles)."""
    figures = {m for m in MODULES if re.fullmatch(r"tiltpile\.figures\.(fig\d|preparation|zcount)", m)}
    for m in sorted(figures):
        others = {t for t, _ in imports_of(m)} & figures - {m}
        allowed = {"tiltpile.figures.fig2"} if m.endswith("preparation") else set()
        assert others <= allowed, f"{m} imports {sorted(others)}: move what they share to a shared module"


# -- the scratch tree and make -n -------------------------------------------------------------------

OLD_STAMPS = (["data/default/.runs", "notebooks/executed/preparation/.inputs",
               "notebooks/executed/preparation/preparation.parameters.yaml"]
              + [f"notebooks/executed/default/{nb.stem}.parameters.yaml" for nb in FIG_NOTEBOOKS])
PLAN_ARGS = ["figures", "preparation", "zcount", "PREP_DIRS=data/prep"]


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    """A copy of what the build reads, every output up to date (sources at t0, stamps at t1,
    outputs at t2, the report at t3)."""
    d = tmp_path_factory.mktemp("build")
    shutil.copy2(ROOT / "Makefile", d)
    for name in ("environment.txt", "pyproject.toml"):
        shutil.copy2(ROOT / name, d)
    shutil.copytree(SRC, d / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    (d / "notebooks").mkdir()
    for nb in (ROOT / "notebooks").glob("*.ipynb"):
        shutil.copy2(nb, d / "notebooks")
    t0, t1, t2, t3 = 1_000_000_000, 1_000_001_000, 1_000_002_000, 1_000_003_000
    for p in d.rglob("*"):
        if p.is_file():
            os.utime(p, (t0, t0))

    def make(rel, t, text="{}\n"):
        p = d / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
        os.utime(p, (t, t))

    for rel in OLD_STAMPS:
        make(rel, t1, "")
    make(".venv/.tiltpile-installed", t1, "")
    make("notebooks/executed/default/diagnostics/.executed", t2, "")
    for nb in FIG_NOTEBOOKS:
        make(f"figures/{nb.stem}.json", t2)
    for rel in SCALE_JSON + STUDY_JSON:
        make(rel, t1)
    make("notebooks/executed/preparation/.executed", t2, "")
    make("notebooks/executed/preparation/.zcount", t2, "")
    make("paper/REPRODUCTION.md", t3, "")
    make("figures/REPRODUCTION.md", t3, "")
    return d


def _plan(tree: Path, *edited) -> set[str]:
    """The targets `make -n figures preparation zcount` would rebuild if ``edited`` were edited."""
    args = ["make", "-n", *[f"-W{e}" for e in edited], *[f"-o{s}" for s in OLD_STAMPS], *PLAN_ARGS]
    r = subprocess.run(args, cwd=tree, capture_output=True, text=True, timeout=120, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr
    out = set(re.findall(r"--no-progress-bar notebooks/(\w+)\.ipynb", r.stdout))
    out -= {"run_diagnostics"}
    if "tiltpile report" in r.stdout:
        out.add("report")
    if "tiltpile zcount" in r.stdout:
        out.add("zcount")
    return out


def test_nothing_rebuilds_when_nothing_changed(tree):
    assert _plan(tree) == set()


# a file of each kind of the package: analysis, a figure, the shared figure code, the report,
# a command, the simulator, the benchmarks, the package's version
SAMPLED = ["src/tiltpile/analysis/contacts.py", "src/tiltpile/figures/fig5.py",
           "src/tiltpile/figures/build.py", "src/tiltpile/report/main.py",
           "src/tiltpile/cli/zcount.py", "src/tiltpile/sim/step.py", "src/tiltpile/__init__.py",
           "src/tiltpile/paper_values.py"]


@pytest.mark.parametrize("rel", SAMPLED)
def test_an_edit_of_the_package_rebuilds_everything(tree, rel):
    assert _plan(tree, rel) == EVERYTHING, f"editing {rel}"


def test_every_file_of_the_package_is_a_dependency(tree):
    """What make lists as the package is every module of src/tiltpile."""
    r = subprocess.run(["make", "-s", "--eval", "show-package: ; @echo $(PACKAGE)", "show-package"],
                       cwd=tree, capture_output=True, text=True, timeout=60, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr
    listed = set(r.stdout.split())
    want = {str(p.relative_to(tree)) for p in (tree / "src" / "tiltpile").rglob("*.py")}
    assert listed == want


@pytest.mark.parametrize("nb", FIG_NOTEBOOKS + [ROOT / "notebooks" / "preparation.ipynb"],
                         ids=lambda p: p.stem)
def test_a_notebook_rebuilds_its_own_target(tree, nb):
    rel = nb.relative_to(ROOT)
    want = {nb.stem} | ({"report"} if nb.stem.startswith("fig") else set())
    assert _plan(tree, rel) == want


def test_the_report_rebuilds_when_any_json_it_reads_changes(tree):
    from tiltpile.report import root_inputs

    read = {p.relative_to(tree) for p in root_inputs(tree / "figures")}
    assert set(SCALE_JSON) | set(STUDY_JSON) <= read
    for rel in sorted(read):
        assert "report" in _plan(tree, rel), f"the report does not rebuild when {rel} changes"
    assert _plan(tree, "figures/smoke/fig2_avalanche_criterion.json") == {"report"}


@pytest.mark.parametrize("preset", ["default", "default-fresh", "paper", "smoke"])
def test_the_report_target_lists_what_the_report_reads_at_every_scale(tree, preset):
    """The Makefile's REPORT_READS holds every file tiltpile.report.inputs finds for the preset's
    figures directory, and its ALL_REPORT_READS every file the main report and paper/STUDIES.md
    read (tiltpile.report.root_inputs)."""
    from tiltpile.report import inputs, root_inputs

    r = subprocess.run(["make", "-s", "--eval",
                        "show-reads: ; @echo $(FIGURES) $(REPORT_READS) , $(ALL_REPORT_READS)",
                        "show-reads", f"PRESET={preset}"], cwd=tree, capture_output=True, text=True,
                       timeout=60, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr
    own, every = r.stdout.split(" , ")
    figures, *listed = own.split()
    read = {p.relative_to(tree).as_posix() for p in inputs(tree / figures)}
    assert read and read <= set(listed), sorted(read - set(listed))
    main = {p.relative_to(tree).as_posix() for p in root_inputs(tree / "figures")}
    assert len(main) > 5 and main <= set(every.split()), sorted(main - set(every.split()))


def test_a_missing_study_output_is_rebuilt(tree):
    (tree / "figures/zcount.json").rename(tree / "figures/zcount.json.away")
    try:
        assert _plan(tree) == {"zcount"}
    finally:
        (tree / "figures/zcount.json.away").rename(tree / "figures/zcount.json")


def test_the_paper_scale_preparation_study_reads_the_committed_records(tree):
    """make preparation-paper: the study on the two paper-scale record directories, fresh first
    (the reference), slides at 1e-3, into figures/paper with its own executed directory (the
    default study's stamps stay where they are)."""
    r = subprocess.run(["make", "-n", "preparation-paper"], cwd=tree, capture_output=True,
                       text=True, timeout=120, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr
    out = " ".join(r.stdout.split())
    assert ('"data_dirs": ["figures/paper-fresh/records","figures/paper/records"]' in out
            and '"figures_dir": "figures/paper"' in out and "-- -p slide_ke 0.001" in out)
    assert "notebooks/executed/preparation-paper/preparation.ipynb" in out
    assert "notebooks/executed/preparation/" not in out


# -- notebook parameters (NB) -------------------------------------------------------------------------

def _files(d: Path) -> dict:
    return {p: p.stat().st_mtime_ns for p in d.rglob("*") if p.is_file()}


def _make(tree: Path, *args) -> subprocess.CompletedProcess:
    import sys

    return subprocess.run(["make", f"PY={sys.executable}", *args], cwd=tree, capture_output=True,
                          text=True, timeout=300, env=MAKE_ENV)


@pytest.mark.parametrize("goal, nb, named", [
    ("figures", "-p epss 0.01", "epss"),                                  # a typo
    ("figures/t/fig5_cluster_sizes.json", "-p slide_ke 0.001", "slide_ke"),  # Fig. 5 does not read it
    ("figures", "-p data_dir /tmp -p eps 0.01", "data_dir"),              # make sets it
    ("preparation", "-p ke_factor 3", "ke_factor"),                       # a Fig. 2 parameter
    ("figures", "--kernel python3", "--kernel"),                          # not a parameter
])
def test_a_notebook_parameter_no_notebook_reads_stops_make_before_anything_runs(tree, goal, nb, named):
    before = _files(tree)
    r = _make(tree, goal, "VARIANT=t", f"NB={nb}", "PREP_DIRS=data/prep")
    assert r.returncode != 0
    ours = [line for line in r.stderr.splitlines() if named in line and not line.startswith("make")]
    assert len(ours) == 1 and ours[0].startswith("NB"), r.stderr
    assert "ensemble" not in r.stdout and "papermill" not in r.stdout
    assert _files(tree) == before


def test_nb_for_a_goal_without_notebooks_is_an_error(tree):
    r = _make(tree, "zcount", "VARIANT=t", "NB=-p eps 0.01", "PREP_DIRS=data/prep")
    assert r.returncode != 0 and "NB: none of the goals (zcount)" in r.stderr


def test_each_notebook_gets_the_parameters_it_declares(tree):
    """make -n: the check first, then per figure a parameters file that papermill reads (-f),
    written by `select` with what that figure takes, as its ``overrides``; NB itself goes to no
    papermill."""
    import sys

    r = subprocess.run(["make", "-n", "figures", "VARIANT=t", "NB=-p eps 0.01 -p ke_factor 3"],
                       cwd=tree, capture_output=True, text=True, timeout=120, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.replace("\\\n", " ").splitlines()     # each command on one line
    assert "tiltpile.figures.parameters check notebooks/fig1_isostaticity.ipynb" in lines[0]
    runs = [line for line in lines if "-m papermill" in line]
    assert len(runs) == len(FIG_NOTEBOOKS) + 1          # and run_diagnostics
    for nb in FIG_NOTEBOOKS:
        run = next(line for line in runs if f" notebooks/{nb.stem}.ipynb " in line)
        assert f" -f notebooks/executed/default-t/{nb.stem}.parameters.yaml " in run
    assert not any("ke_factor" in line for line in runs)
    out = subprocess.run([sys.executable, "-m", "tiltpile.figures.parameters", "select",
                          str(ROOT / "notebooks/fig5_cluster_sizes.ipynb"), "--note", "x",
                          "--", "-p", "eps", "0.01", "-p", "ke_factor", "3"],
                         capture_output=True, text=True, check=True).stdout
    assert out == "# x\noverrides:\n  eps: 0.01\n"      # a figure's share, as its overrides


def test_make_ensemble_runs_a_copy_of_the_committed_code_and_skips_recorded_seeds():
    """make ensemble: the ensemble alone, from `git archive` of HEAD into DATA-code/COMMIT/src
    (PYTHONPATH, and a numba cache of its own), skipping the seeds recorded in RECORDS where
    there are records (the paper's are committed; the smoke preset has none)."""
    head = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True).stdout.strip()
    if not head:
        pytest.skip("not a git checkout")
    r = subprocess.run(["make", "-n", "ensemble", "PRESET=paper", "DATA=/x/runs/paper", "WORKERS=2"],
                       cwd=ROOT, capture_output=True, text=True, timeout=120, env=MAKE_ENV)
    assert r.returncode == 0, r.stderr
    out = " ".join(r.stdout.replace("\\\n", " ").split())
    code = f"/x/runs/paper-code/{head}"
    assert f"git archive {head} src | tar -x -C {code}.tmp && mv {code}.tmp {code}" in out
    assert (f"NUMBA_CACHE_DIR={code}/numba-cache PYTHONPATH={code}/src" in out
            and "-m tiltpile ensemble --preset paper --runs 50 --out /x/runs/paper --workers 2 "
                "--skip-recorded figures/paper/records --quiet" in out)
    r = subprocess.run(["make", "-n", "ensemble", "PRESET=smoke", "DATA=/x/runs/smoke"], cwd=ROOT,
                       capture_output=True, text=True, timeout=120, env=MAKE_ENV)
    assert r.returncode == 0 and "--skip-recorded" not in r.stdout, r.stderr
    # RERUN=1: the recorded seeds again (their run files, for an analysis the records cannot do)
    r = subprocess.run(["make", "-n", "ensemble", "PRESET=paper-fast", "DATA=/x/runs/paper-fast",
                        "RUNS=11", "FIRST=2", "RERUN=1"], cwd=ROOT, capture_output=True, text=True,
                       timeout=120, env=MAKE_ENV)
    out = " ".join(r.stdout.replace("\\\n", " ").split())
    assert r.returncode == 0 and "--skip-recorded" not in out, r.stderr
    assert "--preset paper-fast --runs 11 --out /x/runs/paper-fast --first-seed 2 --quiet" in out


_KERNELS = r"""
import ctypes, glob, json, os
import numpy, scipy
from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
blas = {}
for pkg, sym in ((numpy, "scipy_openblas_get_corename64_"), (scipy, "scipy_openblas_get_corename")):
    libs = glob.glob(os.path.join(os.path.dirname(os.path.dirname(pkg.__file__)),
                                  pkg.__name__ + ".libs", "libscipy_openblas*.so"))
    if libs and hasattr(ctypes.CDLL(libs[0]), sym):
        f = getattr(ctypes.CDLL(libs[0]), sym)
        f.restype = ctypes.c_char_p
        blas[pkg.__name__] = f().decode()
print(json.dumps({"on": [t for t in __cpu_dispatch__ if __cpu_features__.get(t)], "blas": blas}))
"""


def test_the_analysis_runs_with_avx2_kernels_on_any_x86_machine():
    """make runs the analysis (observables, records, notebooks, zcount) with numpy's dispatch held
    at X86_V3 (AVX2) and OpenBLAS's kernels at Haswell, so that an AVX-512 machine computes the
    same figure JSON, bit for bit, as an AVX2 one (their vectorized exp/log/power and BLAS kernels
    differ in the last bits)."""
    import platform
    import sys

    if platform.machine() != "x86_64":
        pytest.skip("the AVX2 level is an x86-64 one")
    env = subprocess.run(["make", "-s", "--eval", "show-env: ; @printf '%s' '$(ANALYSIS_ENV)'", "show-env"],
                         cwd=ROOT, capture_output=True, text=True, env=MAKE_ENV).stdout.strip()
    avx2 = "avx2" in Path("/proc/cpuinfo").read_text().split()
    assert "NPY_DISABLE_CPU_FEATURES=" in env and ("OPENBLAS_CORETYPE=Haswell" in env) == avx2
    got = json.loads(subprocess.run(f"{env} {sys.executable} -c '{_KERNELS}'", shell=True, cwd=ROOT,
                                    capture_output=True, text=True, check=True).stdout)
    assert not set(got["on"]) - {"X86_V3"}, got
    if avx2:
        assert set(got["blas"].values()) == {"Haswell"}, got
    # every analysis recipe carries it: a figure's notebook among them
    r = subprocess.run(["make", "-n", "-B", "figures/fig2_avalanche_criterion.json", "FROM=records",
                        "RECORDS=figures/paper/records"], cwd=ROOT, capture_output=True, text=True,
                       timeout=120, env=MAKE_ENV)
    line = next(x for x in r.stdout.splitlines() if "-m papermill" in x)
    assert line.lstrip("@").startswith(env.split("=")[0] + "="), line
