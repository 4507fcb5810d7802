"""Whether an edit of the analysis keeps the tables' values: the columns of an older commit's
code and of this one on the same run files, bit for bit, and the code entries that follow.

An edit that reaches a column's producer gives the column a new code
(:func:`tiltpile.analysis.tables.column_code`), and a record holding the column under its old
code stops serving it. When the edit keeps every value at the parameters the records hold (a new
parameter at its default, a function moved, a loop rewritten), this tool shows it and prints
the entries of :data:`tiltpile.analysis.legacy_codes.SUPERSEDED` ({old code: new code}) that let
the records keep serving the column::

    python -m benchmarks.code_change OLD_COMMIT RUN_FILE [RUN_FILE ...] [--params JSON ...]

The older commit's ``src/`` is taken from git (``git archive``) into a temporary directory and
run in a subprocess with the same interpreter; both compute
:func:`tiltpile.analysis.tables.run_observables` of every run file at every parameter set given
(default: the default parameters; ``--params '{"cutoff": 0.04}'`` adds a set). A column is the
same when its dtype and every value (NaN where NaN) agree in every run at every set. Exit
status 1 when a column differs (it is listed; its records need the run files).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

_CHILD = r"""
import json, sys
import numpy as np
from tiltpile.analysis.tables import run_observables, column_code
out, runs, sets = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
arrays = {}
for r, path in enumerate(runs):
    for s, params in enumerate(sets):
        frames, clusters = run_observables(path, **params)
        for table, df in (("frames", frames), ("clusters", clusters)):
            for c in df.columns:
                arrays[f"{r}|{s}|{table}|{c}"] = df[c].to_numpy()
np.savez(out + ".npz", **arrays)
open(out + ".json", "w").write(json.dumps(column_code()))
"""


def tables_of(src: Path | None, runs: list[str], sets: list[dict], workdir: Path) -> tuple[dict, dict]:
    """{(run, set, table, column): values} and the column codes, computed by the ``tiltpile``
    package under ``src`` (None: this one) in a subprocess."""
    import os

    out = workdir / ("old" if src is not None else "new")
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = str(src)
        env["NUMBA_CACHE_DIR"] = str(workdir / "numba-cache")
    subprocess.run([sys.executable, "-c", _CHILD, str(out), json.dumps(runs), json.dumps(sets)],
                   check=True, env=env)
    with np.load(str(out) + ".npz", allow_pickle=False) as z:
        values = {tuple(k.split("|")): z[k] for k in z.files}
    return values, json.loads(Path(str(out) + ".json").read_text())


def same(a: np.ndarray, b: np.ndarray) -> bool:
    """The same dtype and the same values, NaN where NaN."""
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.dtype.kind == "f":
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(np.array_equal(a, b))


def compare(old: dict, new: dict, old_codes: dict, new_codes: dict) -> dict:
    """Per column of the old code: same (every run, every set) or not, and its old and new code.
    Returns {"same": {table: [columns]}, "different": {table: [columns]}, "superseded": {old:
    new} for the columns that are the same and whose code changed (a code shared by several
    columns is superseded only when all its columns are the same and map to one new code)}."""
    keys = {(t, c) for (_, _, t, c) in old}
    out = {"same": {}, "different": {}}
    ok = {}
    for table, col in sorted(keys):
        good = all((r, s, t, c) in new and same(v, new[(r, s, t, c)])
                   for (r, s, t, c), v in old.items() if (t, c) == (table, col))
        good = good and col in new_codes.get(table, {})
        out["same" if good else "different"].setdefault(table, []).append(col)
        ok[(table, col)] = good
    by_old: dict = {}
    for (table, col), good in ok.items():
        o = old_codes[table][col]
        by_old.setdefault(o, []).append((good, new_codes.get(table, {}).get(col)))
    out["superseded"] = {o: news[0][1] for o, news in sorted(by_old.items())
                         if all(g for g, _ in news) and len({n for _, n in news}) == 1
                         and news[0][1] != o}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.code_change",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("old", help="the older commit (anything git rev-parse takes)")
    ap.add_argument("runs", nargs="+", help="run files (run_*.h5)")
    ap.add_argument("--params", action="append", default=[],
                    help="a JSON object of analysis parameters (repeatable); the defaults always")
    a = ap.parse_args(argv)
    try:
        sets = [{}] + [json.loads(p) for p in a.params]
    except json.JSONDecodeError as e:
        ap.error(f"--params is not JSON: {e}")
    runs = [str(Path(r).resolve()) for r in a.runs]
    missing = [r for r in runs if not Path(r).is_file()]
    if missing:
        ap.error(f"no run file {missing[0]}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        tar = subprocess.run(["git", "archive", a.old, "src"], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tmp)], input=tar, check=True)
        old, old_codes = tables_of(tmp / "src", runs, sets, tmp)
        new, new_codes = tables_of(None, runs, sets, tmp)
    res = compare(old, new, old_codes, new_codes)
    for table, cols in res["different"].items():
        print(f"different: {table}: {', '.join(cols)}")
    n_same = sum(len(c) for c in res["same"].values())
    print(f"{n_same} columns the same in {len(runs)} run(s) at {len(sets)} parameter set(s)")
    print(json.dumps(res["superseded"], indent=4))
    return 1 if res["different"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
