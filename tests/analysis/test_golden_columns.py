"""Every column's values against its version (tests/analysis/golden.py): a value moved under an
unchanged code fails, naming the columns, so that a producer's version is bumped with every
edit that changes what it gives; and a refactor that changes no value (a producer moved to
another module, its helpers renamed) changes neither a code nor a value."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import golden
from codehelpers import edit, refactor

SRC = golden.ROOT / "src"


def test_every_column_keeps_its_golden_values_under_its_code():
    values, codes = golden.compute()
    want, want_codes = golden.load()
    diff = golden.differences(values, codes, want, want_codes)
    assert not diff["values"], (
        f"values moved under an unchanged code: {', '.join(diff['values'][:10])}: bump the "
        "version of their producers (@_produces(..., version=N) in "
        "src/tiltpile/analysis/tables.py), then `python tests/analysis/golden.py --update`")
    assert not diff["codes"] and not diff["missing"] and not diff["gone"], (
        f"codes changed {diff['codes']}, new columns {diff['missing']}, columns gone "
        f"{diff['gone']}: `python tests/analysis/golden.py --update` (it lists the records a "
        "bump strands)")
    assert set(values) == set(want)


def test_the_fixture_exercises_every_column():
    """Each column takes more than one value in some parameter set (a constant column could not
    show a changed computation), the onsets included."""
    want, _ = golden.load()
    flat = {}
    for key, v in want.items():
        flat.setdefault(key.split("/", 1)[1], []).append(v)
    constant = [c for c, vs in flat.items()
                if all(np.unique(v[~np.isnan(v)] if v.dtype.kind == "f" else v).size <= 1
                       for v in vs) and c not in ("frames.run", "clusters.run",
                                                  "frames.n_mobile")]
    assert constant == []
    assert want["default/frames.onset"].sum() >= 3 and want["default/clusters.size"].size > 100


def test_the_comparison_tells_a_moved_value_from_a_bumped_code():
    values, codes = golden.load()
    moved = dict(values)
    moved["default/frames.z"] = values["default/frames.z"] * (1 + 1e-9)
    assert golden.differences(moved, codes, values, codes)["values"] == ["default/frames.z"]
    bumped = dict(codes, **{"frames.z": "0" * 16})
    d = golden.differences(moved, bumped, values, codes)
    assert d["values"] == [] and d["codes"] == ["frames.z"]
    ints = dict(values)
    ints["default/frames.n_active"] = values["default/frames.n_active"].astype(np.int32)
    assert golden.differences(ints, codes, values, codes)["values"] == ["default/frames.n_active"]


def _in_copy(tmp_path: Path, *edits) -> tuple[dict, dict]:
    """(golden values, codes) computed by a scratch copy of src/ after ``edits`` (callables on
    the copy, or (file under tiltpile/, old, new)), in a fresh interpreter."""
    src = tmp_path / "src"
    shutil.copytree(SRC / "tiltpile", src / "tiltpile", ignore=shutil.ignore_patterns("__pycache__"))
    for e in edits:
        e(src) if callable(e) else edit(src / "tiltpile" / e[0], e[1], e[2])
    out = tmp_path / "values.npz"
    code = ("import json, sys, numpy as np; sys.path.insert(0, %r); import golden, "
            "tiltpile.analysis.tables as t; assert t.__file__.startswith(%r), t.__file__; "
            "v, c = golden.compute(); np.savez(%r, **v); print(json.dumps(c))"
            % (str(Path(golden.__file__).parent), str(src), str(out)))
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    with np.load(out) as z:
        return {k: z[k] for k in z.files}, json.loads(r.stdout.splitlines()[-1])


@pytest.mark.slow
def test_a_refactor_keeps_every_code_and_value_and_a_changed_value_is_caught(tmp_path):
    values, codes = golden.compute()
    # the producer moved to another module, its helpers renamed: nothing moves
    v, c = _in_copy(tmp_path / "refactor", refactor)
    assert c == codes
    assert golden.differences(v, c, values, codes) == {"values": [], "codes": [], "missing": [],
                                                       "gone": []}
    # the active-contact rule changed (f_n > 0.05 m g) without a bump: caught, naming what moved
    v, c = _in_copy(tmp_path / "changed", ("analysis/contacts.py",
                                           "return force[:, 0] > 0.0", "return force[:, 0] > 0.05"))
    assert c == codes
    moved = {k.split("/", 1)[1] for k in golden.differences(v, c, values, codes)["values"]}
    assert {"frames.z", "frames.n_active", "clusters.size"} <= moved
    assert not moved & {"frames.ke_trans", "frames.theta_deg", "frames.step"}
