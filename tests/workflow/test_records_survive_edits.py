"""The committed paper records survive analysis refactors (issues 54, 71): in a scratch copy of
the repository, moving a producer to another module, renaming its helpers, adding a column to the
tables and editing a docstring leave Fig. 2 rebuilt bit for bit from the committed records by
`make`; bumping the version of a column Fig. 2 reads makes `make` refuse Fig. 2 in one line
naming the column.

What it runs, to stay cheap: the Fig. 2 target of `make` (PRESET=paper, from the 50 records of
figures/paper/records), twice, in a copy of the files that target reads (Makefile, src/,
notebooks/, figures/paper/) whose Python code is the copy's (PYTHONPATH; the copy's own refusal
in the second step shows the kernel ran it). Fig. 2 reads the lost-contact columns, the onsets
and the coordination, so it stands for the figures built on them; tests/figures/test_records.py
checks that every figure computes the same numbers from the columns it declares alone.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from codehelpers import add_column, edit, refactor
from makehelpers import MAKE_ENV

ROOT = Path(__file__).resolve().parents[2]
FIG2 = "figures/paper/fig2_avalanche_criterion.json"


def _copy(dst: Path) -> None:
    """The files the Fig. 2 target reads, with their times (so that make sees the copy as built
    and the environment as set up: .venv is the checkout's, linked)."""
    for f in ("Makefile", "pyproject.toml", "environment.txt"):
        shutil.copy2(ROOT / f, dst / f)
    ignore = shutil.ignore_patterns("__pycache__", "executed", "*.pyc")
    shutil.copytree(ROOT / "src", dst / "src", ignore=ignore, copy_function=shutil.copy2)
    shutil.copytree(ROOT / "notebooks", dst / "notebooks", ignore=ignore,
                    copy_function=shutil.copy2)
    shutil.copytree(ROOT / "figures" / "paper", dst / "figures" / "paper",
                    copy_function=shutil.copy2)
    (dst / ".venv").symlink_to(ROOT / ".venv")


def _make(where: Path, numba_cache: Path) -> subprocess.CompletedProcess:
    env = dict(MAKE_ENV, PYTHONPATH=str(where / "src"), NUMBA_CACHE_DIR=str(numba_cache))
    return subprocess.run(["make", FIG2, "PRESET=paper"], cwd=where, capture_output=True,
                          text=True, timeout=1200, env=env)


@pytest.mark.slow
def test_paper_records_survive_a_refactor_and_refuse_a_bumped_column(tmp_path):
    if not (ROOT / ".venv" / "bin" / "python").exists():
        pytest.skip("needs the checkout's .venv (make setup)")
    repo = tmp_path / "repo"
    repo.mkdir()
    _copy(repo)
    committed = (ROOT / FIG2).read_bytes()
    # a producer moved to another module, helpers renamed, a new column, a docstring edit
    refactor(repo / "src")
    add_column(repo / "src")
    edit(repo / "src/tiltpile/analysis/contacts.py", '"""Active contacts: normal force f_n > 0.',
         '"""Active contacts: normal force f_n > 0 (an edited docstring).')
    r = _make(repo, tmp_path / "numba")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "papermill notebooks/fig2_avalanche_criterion.ipynb" in r.stdout   # rebuilt, not skipped
    assert (repo / FIG2).read_bytes() == committed
    # the lost contacts, which Fig. 2 reads, at a new version: refused, naming the column
    edit(repo / "src/tiltpile/analysis/tables.py", '           fill={"frames.n_lost": -1,',
         '           version=2, fill={"frames.n_lost": -1,')
    r = _make(repo, tmp_path / "numba")
    out = r.stdout + r.stderr
    assert r.returncode != 0
    assert "Fig. 2 (figures/paper/records) needs column frames.n_lost; its records hold it as " \
           "other code computed it" in out, out[-3000:]
    assert "the run files are needed" in out
    assert (repo / FIG2).read_bytes() == committed           # nothing written
