"""The tables' declarations, their producers and each column's code (tiltpile.analysis.tables,
tiltpile.analysis.legacy_codes)."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tiltpile.analysis.observables as ob
from tiltpile.analysis import legacy_codes, tables
from tiltpile.analysis.ensemble_data import record_columns
from tiltpile.record import read_meta, record_files

from codehelpers import add_column, edit, refactor

SRC = Path(tables.__file__).resolve().parents[2]
ROOT = SRC.parent
def _codes(tmp_path, *edits) -> dict:
    """column_code() of a scratch copy of src/ after ``edits`` ((file under tiltpile/, old, new)
    or a callable on the copy), in a fresh interpreter."""
    src = tmp_path / "src"
    shutil.copytree(SRC / "tiltpile", src / "tiltpile",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for e in edits:
        if callable(e):
            e(src)
        else:
            edit(src / "tiltpile" / e[0], e[1], e[2])
    env = dict(os.environ, PYTHONPATH=str(src))
    out = subprocess.run([sys.executable, "-c", "import json, tiltpile.analysis.tables as t; "
                          "print(t.__file__); print(json.dumps(t.column_code()))"],
                         env=env, capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0].startswith(str(src))          # the copy's code, not the installed one
    return json.loads(out[1])


def _changed(a: dict, b: dict) -> set:
    return {f"{t}.{c}" for t in a for c in a[t] if b[t].get(c) != a[t][c]}


def test_the_codes_are_the_versions_of_each_column(tmp_path):
    codes = tables.column_code()
    assert _codes(tmp_path / "copy") == codes
    assert all(len(d) == 16 for t in codes.values() for d in t.values())
    assert list(codes["frames"]) == tables.FRAME_COLUMNS
    assert list(codes["clusters"]) == tables.CLUSTER_COLUMNS
    # one producer, one code: z and n_m share theirs; the kinetic energy reads no producer
    assert codes["frames"]["z"] == codes["frames"]["n_m"] != codes["frames"]["ke_trans"]
    # the onset is the segmentation's, which reads the lost fraction
    onset = tables.producer_code("frames.onset")
    assert onset == tables.producer_code("segments") != tables.producer_code("frames.lost_fraction")


def test_documentation_code_edits_a_refactor_and_a_new_column_keep_the_codes(tmp_path):
    """What keeps every code: docstrings, comments, new code, a producer moved to another module
    with its helpers renamed, a new column, and any edit of the code (whether it keeps the values
    is the golden values' test, tests/analysis/test_golden_columns.py)."""
    before = tables.column_code()
    after = _codes(tmp_path,
                   ("analysis/contacts.py", '"""Active contacts: normal force f_n > 0.',
                    '"""Active contacts: normal force f_n > 0 (edited).'),
                   ("analysis/clusters.py", "from .contacts import _contact_counts, _dz_local",
                    "# a new comment\nfrom .contacts import _contact_counts, _dz_local  # and another"),
                   ("analysis/tables.py", '"""The observables\' tables:', '"""The tables (edited):'),
                   ("analysis/tables.py", '"bulk grains (rattlers removed)"', '"bulk grains (edited)"'),
                   ("analysis/avalanche.py", "MIN_LOST_CONTACTS = 3.0", "MIN_LOST_CONTACTS = 4.0"),
                   refactor, add_column)
    assert _changed(before, after) == set()
    assert "n_wall_contacts" in after["frames"]


@pytest.mark.parametrize("change, changed, kept", [
    # the active-contact rule's version: every count, what follows from the lost fraction, the
    # clusters
    (("analysis/tables.py", '@_produces("frame", gives=("contacts",),',
      '@_produces("frame", gives=("contacts",), version=2,'),
     {"frames.z", "frames.n_active", "frames.lost_fraction", "frames.onset", "frames.theta_m",
      "frames.rigid_fraction", "clusters.size", "clusters.avalanching"},
     {"frames.ke_trans", "frames.step", "frames.theta_deg", "clusters.run"}),
    # the lost contacts' version: what follows from them, not the counts
    (("analysis/tables.py", '           fill={"frames.n_lost": -1,',
      '           version=2, fill={"frames.n_lost": -1,'),
     {"frames.n_lost", "frames.lost_fraction", "frames.avalanching", "frames.onset",
      "frames.theta_m", "frames.theta_to_onset", "frames.mean_displacement",
      "clusters.avalanching", "clusters.theta_to_onset"},
     {"frames.z", "frames.rigid_fraction", "clusters.size", "clusters.theta_deg"}),
    # the engine's version: every column
    (("analysis/tables.py", "ENGINE_VERSION = 1", "ENGINE_VERSION = 2"),
     {f"frames.{c}" for c in tables.FRAME_COLUMNS} | {f"clusters.{c}" for c in tables.CLUSTER_COLUMNS},
     set()),
])
def test_a_version_bump_changes_the_codes_of_the_columns_it_reaches(tmp_path, change, changed, kept):
    diff = _changed(tables.column_code(), _codes(tmp_path, change))
    assert changed <= diff and not kept & diff


def test_a_version_is_an_integer_of_at_least_one():
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="version must be an integer >= 1"):
            tables._produces("frame", gives=("x",), version=bad)


def test_a_producer_reads_only_what_it_declares():
    reg = tables.Producer("frame", lambda q: {"x": q["fixed"]}, ("x",), ("radius",), {})
    with pytest.raises(KeyError, match="reads 'fixed' without declaring it"):
        reg.fn(tables._View({"fixed": 1, "radius": 2}, reg))


def test_a_producer_cannot_change_what_another_gave():
    """What producers give (and the stages' inputs) reach later producers as read-only views,
    leaving the originals writable: no producer changes a value another one's version covers."""
    a = np.zeros(3)
    given = tables._given(tables._GIVER["bulk"], {k: {"z_i": a} if k == "bulk" else 0
                                                   for k in tables._GIVER["bulk"].gives})
    with pytest.raises(ValueError, match="read-only"):
        given["bulk"]["z_i"][0] = 1.0
    a[0] = 1.0
    assert given["bulk"]["z_i"][0] == 1.0            # a view, not a copy


def test_the_legacy_table_code_holds_the_committed_records_columns():
    """The 58 committed records hold the whole-table digest 11ce282f6e591a47, which
    legacy_codes maps to the producers' codes: every column they hold has an entry, and every
    figure's columns are served by them as they are (their bytes are never rewritten)."""
    from tiltpile.figures import build, preparation
    entry = legacy_codes.LEGACY["11ce282f6e591a47"]
    paths = record_files(ROOT / "figures" / "paper" / "records") + \
        record_files(ROOT / "figures" / "paper-fresh" / "records")
    assert len(paths) == 58
    for p in paths:
        meta = read_meta(p)
        assert meta["analysis_code"] == "11ce282f6e591a47" and "column_code" not in meta
        for table in ("frames", "clusters"):
            assert {c for c, _ in meta["columns"][table]} <= set(entry[table])
        assert legacy_codes.recorded_column_code(meta) == {
            t: {c: legacy_codes.superseded(v) for c, v in cols.items()} for t, cols in entry.items()}
        for reads in [m.READS for m in build.MODULES.values()] + [preparation.READS]:
            record_columns(p, meta, reads)
    assert legacy_codes.recorded_column_code({"analysis_code": "0" * 16}) is None
    assert legacy_codes.recorded_column_code({"column_code": {"frames": {"z": "x"}}}) == \
        {"frames": {"z": "x"}}
    assert legacy_codes.recorded_column_code({"column_code": {"frames": {}}}) == {"frames": {}}


def test_superseded_codes_reach_this_tiltpiles_codes():
    """Every superseded code leads, without a cycle, to a code this tiltpile computes (an entry
    pointing nowhere would carry records over to a code no column has), and a record holding the
    old codes of 8c18fdd (the committed records' own) is served every column as it is now."""
    current = {v for cols in tables.column_code().values() for v in cols.values()}
    for old in legacy_codes.SUPERSEDED:
        assert legacy_codes.superseded(old) in current
    entry = legacy_codes.LEGACY["11ce282f6e591a47"]
    held = legacy_codes.recorded_column_code({"column_code": entry})
    assert held == tables.column_code()


def test_code_change_compares_values_dtype_and_nan():
    from benchmarks import code_change as cc
    a = {("0", "0", "frames", "z"): np.array([1.0, np.nan]),
         ("0", "0", "frames", "n"): np.array([1, 2]),
         ("0", "0", "frames", "m"): np.array([1, 2])}
    b = {("0", "0", "frames", "z"): np.array([1.0, np.nan]),
         ("0", "0", "frames", "n"): np.array([1, 2], dtype=np.int32),
         ("0", "0", "frames", "m"): np.array([1, 3])}
    old = {"frames": {"z": "a", "n": "b", "m": "c"}}
    new = {"frames": {"z": "A", "n": "B", "m": "C"}}
    res = cc.compare(a, b, old, new)
    assert res["same"] == {"frames": ["z"]} and sorted(res["different"]["frames"]) == ["m", "n"]
    assert res["superseded"] == {"a": "A"}
    # a code shared by two columns is superseded only when both are the same
    old2 = {"frames": {"z": "s", "m": "s", "n": "b"}}
    assert "s" not in cc.compare(a, b, old2, {"frames": {"z": "S", "m": "S", "n": "B"}})["superseded"]


def test_every_column_is_declared_once_and_documented():
    assert tables.FRAME_COLUMNS == list(tables.FRAME_DOCS)
    assert tables.CLUSTER_COLUMNS == list(tables.CLUSTER_DOCS)
    for docs in (tables.FRAME_DOCS, tables.CLUSTER_DOCS):
        for name, doc in docs.items():
            assert doc.strip() and f"    {name} " in tables.__doc__
    # the observables module re-exports the declarations, it does not keep its own
    assert ob.FRAME_COLUMNS is tables.FRAME_COLUMNS and ob.DEFAULT_PARAMS is tables.DEFAULT_PARAMS


def test_frame_functions_take_the_parameters_by_name():
    radius = np.full(3, 0.5)
    fixed = np.array([True, False, False])
    pos = np.array([[0.5, 0.5], [1.5, 0.5], [1.0, 1.366]])
    pair = np.array([[0, 1], [0, 2], [1, 2]])
    force = np.array([[1.0, 0.0], [1.0, 0.5], [1.0, 0.0]])
    status = np.array([1, 1, 2], dtype=np.int8)
    with pytest.raises(TypeError, match=r"unknown analysis parameter\(s\) \['cut_off'\]"):
        tables.frame_contacts(radius, fixed, 3.0, pos, pair, force, status, cut_off=0.1)
    with pytest.raises(TypeError):     # keywords only: no parameter slips in by position
        tables.frame_contacts(radius, fixed, 3.0, pos, pair, force, status, 0.5)
    a = tables.frame_contacts(radius, fixed, 3.0, pos, pair, force, status)
    b = tables.frame_contacts(radius, fixed, 3.0, pos, pair, force, status, eps=0.01)
    assert a["mobilized"].tolist() == [False, False, True]   # the sliding status
    assert b["mobilized"].tolist() == [False, True, False]   # |f_t| >= mu f_n (1 - eps)



def test_the_rigidity_columns_of_a_frame(pile_factory, contacts_factory):
    """A triangular pile on its fixed row is one rigid cluster from the ground to the surface
    while its contacts stick; with every contact whose lower grain is in row 4 or above sliding
    (1 bar each), rows 5 and 6 come loose, rows 1-4 stay rigid with the ground (2 sticking
    contacts down each: 4 bars for 3 degrees of freedom), and nothing spans."""
    pos, radius, fixed, row = pile_factory(8, 6)
    L = 8.0
    pair = contacts_factory(pos, radius, L)
    force = np.column_stack([np.ones(len(pair)), np.zeros(len(pair))])
    zero = np.zeros_like(pos)

    def rigidity(status):
        r, _, _ = tables.frame_observables(radius, fixed, L, pos, zero, np.zeros(len(radius)),
                                           pair, force, status, 0.0)
        return r["rigid_fraction"], r["floppy_per_grain"], r["rigid_spanning"], r["n_rigid_left_out"]

    frac, floppy, spanning, left_out = rigidity(np.ones(len(pair), dtype=np.int8))
    assert (frac, floppy, spanning, left_out) == (1.0, 0.0, True, 0)
    top = row[pair[:, 0]] >= 4
    frac, floppy, spanning, _ = rigidity(np.where(top, 2, 1).astype(np.int8))
    n_mobile = int((~fixed).sum())
    assert frac == pytest.approx(((row >= 1) & (row <= 4)).sum() / n_mobile)
    assert floppy > 0 and not spanning
