"""The same headline numbers of Fig. 2 at every scale of the report (the presets of
``config.PRESET_TABLE`` with a ``report`` entry; "not yet run" where a scale has no figures), and
where each scale's figures live (:func:`scale_dirs`).
"""

from __future__ import annotations

import math
import statistics
from pathlib import Path

from tiltpile import config as cfgmod

from . import wall as _wall
from .judging import SEPARATION, approx, num as _num, show as _f, show_ci as _ci, wrong_side as _wrong_side


# (scale, its figures directory below the default scale's) of every preset in the report
# (``config.PRESET_TABLE``, whose order is the columns')
def _below_default(figures: str) -> str:
    rel = Path(figures).relative_to(cfgmod.preset_info("default").figures)
    return "" if rel == Path(".") else rel.as_posix()


SCALES = tuple((p.name, _below_default(p.figures)) for p in cfgmod.PRESET_TABLE if p.report)


def scale_dirs(figures_dir) -> dict[str, Path]:
    """{scale: figures directory}: the default scale writes ``figures/``, the others
    ``figures/<scale>/``; from any of them the others are found."""
    d = Path(figures_dir)
    root = d.parent if d.name in {sub for _, sub in SCALES if sub} else d
    return {name: (root / sub if sub else root) for name, sub in SCALES}


def preset_dir(figures_dir, name: str) -> Path:
    """The figures directory of preset ``name`` (any of ``config.PRESET_TABLE``, in the report
    or not), found from the figures directory of any scale of the report."""
    return scale_dirs(figures_dir)["default"] / _below_default(cfgmod.preset_info(name).figures)


def _gap_text(b: dict, cutoff: float) -> str:
    """'yes|no (lower above / upper below, where)': the shares of the two fitted populations on
    the wrong side of the cutoff (the cutoff_in_gap claim's rule)."""
    between = b.get("cutoff_between_means")
    above, below = _wrong_side(b, cutoff)
    if between is None or not (math.isfinite(above) and math.isfinite(below)):
        return "n/a"
    where = "between the means" if between else "beyond both means"
    ok = above <= SEPARATION and below <= SEPARATION
    return f"{'yes' if ok else 'no'} ({_f(above, '.0%')} / {_f(below, '.0%')}, {where})"


def _per_run_angles(n: dict, name: str) -> str:
    """'k of m runs: a, b, ...; tilts end >= e' of fig2's theta_<name>_per_run (the runs with none
    before the end of their tilt counted, not listed; more than 8 angles: their range)."""
    per = [_num(v) for v in (n.get(f"theta_{name}_per_run") or [])]
    fin = sorted(v for v in per if math.isfinite(v))
    if len(fin) > 8:
        listed = f": {_f(fin[0], '.1f')}-{_f(fin[-1], '.1f')}, median {_f(statistics.median(fin), '.1f')}"
    else:
        listed = f": {', '.join(_f(v, '.1f') for v in fin)}" if fin else ""
    return f"{len(fin)} of {len(per)} runs{listed}; tilts end >= {_f(_num(n.get('theta_end_min')), '.0f')}"


def _scale_rows(n2: dict, doc: dict | None) -> dict[str, str]:
    if doc is None:
        return {}
    n = doc.get("numbers", {})
    b = n.get("lost_bimodality") or {}
    return {
        "grains x runs": f"{doc.get('n_grains')} x {doc.get('n_runs')}",
        "first 2% onset (deg)": _ci(n, "theta_m", ".1f", "theta_m_mean"),
        "first sustained flow (deg)": _per_run_angles(n, "slide"),
        "avalanche angle: first large slide (deg)": _per_run_angles(n, "avalanche"),
        "KE threshold (per grain)": _f(_num(n.get("ke_threshold")), ".1e")
            + _loo_flag(n, "ke_threshold"),
        "frames losing no contact": _f(_num(n.get("lost_zero_fraction")), ".0%"),
        "Ashman D / valley depth": f"{_f(_num(b.get('ashman_d')), '.1f')} / {_f(_num(b.get('valley_depth')), '.2f')}",
        "valley at (lost fraction)": _f(_num(b.get("valley")), ".2%") + _loo_range(n, "lost_valley"),
        "cutoff in the gap (lower population above it / upper below it)":
            _gap_text(b, _num(n.get("cutoff"))),
        "<z> quiet": _ci(n, "z_quiet_run_mean", ".3f"),
        "<n_m> quiet": _ci(n, "n_m_quiet_run_mean", ".3f"),
        "quiet frames below the line": _ci(n, "quiet_below_run_mean", ".1%"),
        **_cost_rows(doc),
    }


def _loo_flag(n: dict, key: str) -> str:
    """' (bistable: v for k of m runs left out, ...)' where leaving one run out moves a number
    picked from bins (fig2's ``stability``), '' where it is firm or was not measured."""
    st = (n.get("stability") or {}).get(key) or {}
    if not st or st.get("firm", True):
        return ""
    full = _num(n.get(key))
    other = [f"{_f(v, '.1e')} for {k} of {st.get('n')}" for v, k in zip(st.get("values", []),
                                                                       st.get("counts", []))
             if v != full]
    undefined = sum(1 for v in st.get("per_run_left_out", []) if v is None)
    if undefined:   # no threshold at all with that run left out
        other.append(f"none for {undefined} of {st.get('n')}")
    kind = "bistable" if len(st.get("values", [])) == 2 else "unstable"
    return f" ({kind}: {', '.join(other)} runs left out)"


def _loo_range(n: dict, key: str) -> str:
    """' (low-high leaving one run out)' of fig2's ``stability``, '' where not measured."""
    st = (n.get("stability") or {}).get(key) or {}
    lo, hi = _num(st.get("low")), _num(st.get("high"))
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return ""
    return f" ({_f(lo, '.2%')}-{_f(hi, '.2%')} leaving one run out)"


def _cost_rows(doc: dict) -> dict[str, str]:
    """What a run of the scale cost, from the runs' own cost records (``ensemble_data.ensemble_cost``):
    NLGS sweeps (the JSON's ``cost``), wall time per run (the median over the runs whose whole
    wall time is known, from their committed records: :mod:`.wall`, which ``render_scales``
    reads the document through) and the core-hours of all the runs at that median."""
    cost, n_runs = doc.get("cost") or {}, doc.get("n_runs")
    sweeps, sec, timed = _num(cost.get("sweeps_per_run")), _num(cost.get("seconds_per_run")), cost.get("runs_timed")
    wall = (f"{_f(sec / 60.0, '.1f')} min (median of {timed} of {n_runs} runs)" if math.isfinite(sec)
            else "not recorded whole (resumed runs)" if timed is not None
            else "not committed (no records)")
    hours = (f"~{approx(sec * n_runs / 3600.0, 2)} (median x {n_runs} runs)"
             if math.isfinite(sec) and n_runs else "n/a")
    return {"NLGS sweeps per run": f"{_f(sweeps / 1e6, '.1f')} M" if math.isfinite(sweeps) else "n/a",
            "wall time per run": wall, "core-hours, all runs": hours}


def render_scales(figures_dir) -> list[str]:
    """Markdown lines: Fig. 2's headline numbers per scale ("not yet run" where absent)."""
    cols = {}
    for name, d in scale_dirs(figures_dir).items():
        p = d / "fig2_avalanche_criterion.json"
        cols[name] = _scale_rows({}, _wall.load(p)) if p.exists() else None
    keys = next((list(c) for c in cols.values() if c), [])
    if not keys:
        return []
    lines = ["", "## The same numbers at every scale", "",
             "From `fig2_avalanche_criterion.json` of each preset (`make figures PRESET=...`); "
             "brackets: 95% bootstrap interval over runs. The first sustained flow: kinetic energy "
             "per grain above the Fig. 2a threshold (the KE threshold row) over >= 0.5 deg of tilt; "
             "the avalanche angle: the same above fig2's fixed avalanche_ke (1e-3 unless given).",
             "",
             "| | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for k in keys:
        lines.append(f"| {k} | " + " | ".join(
            (c.get(k, "n/a") if c else "not yet run") for c in cols.values()) + " |")
    return lines
