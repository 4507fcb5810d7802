"""The wall time per run behind a figure document, from the committed records.

A figure's JSON holds what its runs cost that does not depend on the machine (steps, sweeps and
capped steps per run, its ``cost``), not their wall time: that is a fact of the machine and of
the session the runs were simulated in, and writing it would change the committed JSON each time
the runs are simulated afresh (``tiltpile.figures.style.WALL_CLOCK``). Each run's wall time stays
in its run file and in its record, which is committed and does not change. The reports read it
here: the median wall seconds per run of the runs timed whole and how many were
(:func:`tiltpile.analysis.ensemble_data.ensemble_cost`, as the figures' JSON held them before),
over the records the document was computed from:

* a preset's figures, ``<figures>/fig*.json`` beside ``<figures>/records/``: the records of the
  document's seeds (``make figures`` from records reads the first RUNS of them);
* a side of a pile-against-pile study, ``<study>/same-piles/[<setting>/]<label>/``: every record
  of the ensemble the study compared (its header's cost is the whole ensemble's), the study's own
  ``<study>/records/<label>/`` (the solver study's settings) or else those of the preset
  ``label`` (``<its figures>/records/``, found from the study's directory up).

Records of another configuration than the document's (its ``config_hash``), or missing for one
of its seeds, give nothing. A document whose runs have no committed records (smoke, default,
default-fresh: their run files alone hold the wall times, which ``tiltpile info DATA`` prints)
has no wall time in the reports. A document that holds its own (written before the wall time
left the figures' JSON, or by a test) keeps it.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

from tiltpile import config as cfgmod

#: the fields of ``cost`` that the figures' JSON leave out and :func:`wall_time` gives
#: (``tiltpile.figures.style.WALL_CLOCK``, the same names)
WALL_KEYS = ("runs_timed", "seconds_per_run")
SAME_PILES = "same-piles"


def _records(d: Path) -> list[Path]:
    return sorted(d.glob("run_*.npz")) if d.is_dir() else []


def _preset_records(start: Path, label: str) -> Path | None:
    """The records directory of preset ``label``, ``<root>/<its figures below the default's>/records``,
    for ``root`` the first of ``start`` and its parents that holds one."""
    try:
        info = cfgmod.preset_info(label)
    except (KeyError, ValueError):
        return None
    rel = Path(info.figures).relative_to(cfgmod.preset_info("default").figures)
    for root in (start, *start.parents):
        if _records(root / rel / "records"):
            return root / rel / "records"
    return None


def records_of(fig_dir) -> tuple[Path, bool] | None:
    """(records directory, whether the document's seeds alone count) of the figure documents in
    ``fig_dir`` (module docstring); None where none is committed."""
    d = Path(fig_dir)
    if _records(d / "records"):
        return d / "records", True
    parts = d.parts
    if SAME_PILES not in parts[:-1]:
        return None
    study = Path(*parts[:len(parts) - 1 - parts[::-1].index(SAME_PILES)])
    own = study / "records" / d.name
    if _records(own):
        return own, False
    found = _preset_records(study.parent, d.name)
    return (found, False) if found is not None else None


def inputs(fig_dir) -> list[Path]:
    """The records :func:`wall_time` reads for the documents of ``fig_dir`` ([] without any)."""
    found = records_of(fig_dir)
    return _records(found[0]) if found else []


@lru_cache(maxsize=None)
def _costs(records: str, signature: tuple) -> dict[int, tuple[str, dict]]:
    """{seed: (config hash, the record's cost)} of the records in ``records`` (``signature``:
    their names, sizes and times, so that a record written since is read again)."""
    from tiltpile.record import read_meta

    out = {}
    for name, _, _ in signature:
        m = read_meta(Path(records) / name)
        out[int(m["seed"])] = (str(m.get("config_hash") or ""), dict(m.get("cost") or {}))
    return out


def wall_time(fig_dir, doc: dict) -> dict:
    """{"runs_timed", "seconds_per_run"} of the runs behind ``doc`` (a figure document of
    ``fig_dir``) from the committed records (module docstring); {} where they give none."""
    from tiltpile.analysis.ensemble_data import ensemble_cost

    found = records_of(fig_dir)
    if found is None:
        return {}
    records, own_seeds = found
    files = _records(records)
    signature = tuple((p.name, p.stat().st_size, p.stat().st_mtime_ns) for p in files)
    costs = _costs(str(records), signature)
    seeds = [int(s) for s in doc.get("seeds") or []]
    if not seeds or any(s not in costs for s in seeds):
        return {}
    chosen = seeds if own_seeds else sorted(costs)
    want = str(doc.get("config_hash") or "")
    if want and any(not costs[s][0].startswith(want) for s in chosen):
        return {}
    c = ensemble_cost([costs[s][1] for s in chosen])
    return {k: c[k] for k in WALL_KEYS}


def with_wall_time(doc: dict, fig_dir) -> dict:
    """``doc`` with its ``cost`` completed by :func:`wall_time` (a copy; ``doc`` itself where
    it holds its own wall time, has no ``cost`` or the records give none)."""
    cost = doc.get("cost")
    if not isinstance(cost, dict) or any(k in cost for k in WALL_KEYS):
        return doc
    wall = wall_time(fig_dir, doc)
    return {**doc, "cost": {**cost, **wall}} if wall else doc


def load(path) -> dict:
    """A figure document read from ``path``, with the wall time of its runs (:func:`with_wall_time`)."""
    path = Path(path)
    return with_wall_time(json.loads(path.read_text()), path.parent)
