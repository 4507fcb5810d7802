"""Golden values of every column of the observables' tables, on a small committed run.

The columns' codes (tiltpile.analysis.tables.column_code) are made of the producers' versions,
not of their code, so that a refactor strands no record; what keeps a version honest is this: the
tables of ``golden/run.h5`` (61 stored frames of a 250-grain smoke run across its first
avalanches) at each parameter set of ``PARAM_SETS``, every column's values and dtype, held in
``golden/columns.npz`` beside the code each column had when they were written
(``golden/codes.json``). tests/analysis/test_golden_columns.py recomputes them: a column whose
values moved under an unchanged code fails (its producer's version must be bumped), and a
column whose code changed fails until the values are written again.

    python tests/analysis/golden.py --update     # after a version bump: rewrite the golden values
                                                 # and list the committed records it strands

``python tests/analysis/golden.py --cut RUN.h5 START STOP`` wrote ``golden/run.h5`` (from
``data/smoke/run_0000.h5``, frames 130 to 190, of the code of 605d1a5); it is kept for the
record, the fixture is never rewritten.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np

HERE = Path(__file__).resolve().parent / "golden"
FIXTURE = HERE / "run.h5"
VALUES = HERE / "columns.npz"
CODES = HERE / "codes.json"
ROOT = Path(__file__).resolve().parents[2]

# every parameter the tables depend on away from its default at least once, each rule of the
# contact and lost-contact definitions among them
PARAM_SETS = {
    "default": {},
    "touching": {"contact_rule": "touching", "link": "mobilized", "min_contacts": 3},
    "gap": {"contact_rule": "gap:0.01", "lost_rule": "force", "lost_gap": 0.001,
            "cluster_region": "bulk", "ray_spacing": 0.2, "touch_tol": 0.1},
    "threshold": {"eps": 0.01, "cutoff": 0.03, "merge_gap": 2},
    "stride": {"frame_stride": 2, "lost_rule": "touching"},
}


def cut(src: Path, out: Path, start: int, stop: int) -> None:
    """Write stored frames ``start``..``stop - 1`` of run file ``src`` as run file ``out``
    (the store's own writer: the same layout, configuration, grains and frames)."""
    from tiltpile.store import RunWriter, open_run
    from tiltpile.store.layout import FRAME_ARRAYS, FRAME_SCALARS

    with open_run(src) as r:
        w = RunWriter(out, config_json=json.dumps(r.config, sort_keys=True),
                      config_hash=r.config_hash, seed=r.seed, radius=np.asarray(r.radius),
                      fixed=np.asarray(r.fixed), box_length=float(r.box_length), jit={})
        try:
            for k in range(start, stop):
                f = {name: getattr(r, name)[k] for name in FRAME_SCALARS}
                f.update({name: getattr(r, name)(k) for name in FRAME_ARRAYS})
                f["pair"], f["force"], f["status"] = r.contacts(k)
                w.append(SimpleNamespace(**f))
            w.write_end(SimpleNamespace(reason="theta_max", theta_deg=float(r.theta_deg[stop - 1]),
                                        steps=int(r.step[stop - 1]), sweeps=0, capped_steps=0))
            w.finish()
        except BaseException:
            w.close()
            raise


def compute() -> tuple[dict, dict]:
    """({"<set>/<table>.<column>": values}, {"<table>.<column>": code}) of this tiltpile."""
    from tiltpile.analysis import ResolutionWarning
    from tiltpile.analysis.tables import column_code, run_observables

    values = {}
    for name, params in PARAM_SETS.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ResolutionWarning)   # the fixture's frames are few
            frames, clusters = run_observables(FIXTURE, **params)
        for table, df in (("frames", frames), ("clusters", clusters)):
            for c in df.columns:
                values[f"{name}/{table}.{c}"] = df[c].to_numpy()
    codes = {f"{t}.{c}": code for t, cols in column_code().items() for c, code in cols.items()}
    return values, codes


def same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal values and dtype; floats equal to 1e-12 relative (and 1e-300 absolute), so that
    only a summation order (another CPU's vector width) passes, never a changed computation,
    which moves a value by far more."""
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.dtype.kind == "f":
        return bool(np.allclose(a, b, rtol=1e-12, atol=1e-300, equal_nan=True))
    return bool(np.array_equal(a, b))


def differences(values: dict, codes: dict, golden: dict, golden_codes: dict) -> dict:
    """What moved against the golden values: {"values": columns whose values moved under their
    golden code, "codes": columns whose code is not the golden one, "missing": columns the
    golden values do not hold (new ones), "gone": golden columns no longer computed}; each a
    sorted list of ``<table>.<column>`` (values: with the parameter sets, ``set/...``)."""
    moved = sorted(k for k, v in values.items()
                   if k in golden and codes[k.split("/", 1)[1]] == golden_codes.get(k.split("/", 1)[1])
                   and not same(v, golden[k]))
    return {"values": moved,
            "codes": sorted(c for c in codes if c in golden_codes and codes[c] != golden_codes[c]),
            "missing": sorted(c for c in codes if c not in golden_codes),
            "gone": sorted(c for c in golden_codes if c not in codes)}


def load() -> tuple[dict, dict]:
    with np.load(VALUES, allow_pickle=False) as z:
        golden = {k: z[k] for k in z.files}
    return golden, json.loads(CODES.read_text())


def stranded(codes: dict, root: Path = ROOT) -> dict:
    """{records directory: [columns]}: the committed records (``figures/**/run_*.npz``) holding a
    column under another code than ``codes`` (a bumped version strands them)."""
    from tiltpile.analysis.legacy_codes import recorded_column_code
    from tiltpile.record import read_meta

    out: dict = {}
    for path in sorted(root.glob("figures/**/run_*.npz")):
        meta = read_meta(path)
        held = recorded_column_code(meta) or {}
        for table, cols in held.items():
            for c, code in cols.items():
                if f"{table}.{c}" in codes and codes[f"{table}.{c}"] != code:
                    out.setdefault(str(path.parent.relative_to(root)), set()).add(f"{table}.{c}")
    return {d: sorted(c) for d, c in out.items()}


def update() -> None:
    values, codes = compute()
    old_codes = json.loads(CODES.read_text()) if CODES.exists() else {}
    if old_codes:
        golden, _ = load()
        moved = differences(values, codes, golden, old_codes)["values"]
        if moved:
            sys.exit(f"values moved under an unchanged code: {', '.join(moved[:8])}"
                     f"{' ...' if len(moved) > 8 else ''}; bump the version of their producers "
                     "(tiltpile/analysis/tables.py, @_produces(..., version=N)) first")
    HERE.mkdir(exist_ok=True)
    with open(VALUES, "wb") as fh:
        np.savez_compressed(fh, **values)
    CODES.write_text(json.dumps(codes, indent=1, sort_keys=True) + "\n")
    bumped = sorted(c for c in codes if old_codes.get(c, codes[c]) != codes[c])
    print(f"wrote {VALUES.relative_to(ROOT)} and {CODES.relative_to(ROOT)} "
          f"({len(codes)} columns, {len(PARAM_SETS)} parameter sets); codes changed: "
          f"{', '.join(bumped) or 'none'}")
    for d, cols in stranded(codes).items():
        print(f"stranded: {d} holds {', '.join(cols)} under an older code; rewrite its records "
              "from the run files (make records) or keep the old version")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--update", action="store_true", help="rewrite the golden values")
    ap.add_argument("--cut", nargs=3, metavar=("RUN", "START", "STOP"),
                    help="write the fixture from stored frames START..STOP-1 of RUN")
    a = ap.parse_args(argv)
    if a.cut:
        if FIXTURE.exists():
            sys.exit(f"{FIXTURE} exists; the fixture is never rewritten")
        HERE.mkdir(exist_ok=True)
        cut(Path(a.cut[0]), FIXTURE, int(a.cut[1]), int(a.cut[2]))
    if a.update:
        update()


if __name__ == "__main__":
    main()
