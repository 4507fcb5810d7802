"""The studies beside the figures: the preparation study's section of ``paper/STUDIES.md``
(:func:`render_preparation`), the studies' JSON of a figures directory (:func:`load_studies`),
and a parameter study's section (:func:`render_study`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from tiltpile.paper_values import AVALANCHE_DEG, QUIET_DEG, REPOSE_DEG

from .judging import num, show
from .scales import scale_dirs

STUDIES = {"preparation": "preparation.json", "zcount": "zcount.json",
           "definitions": "definitions.json"}


def load_studies(figures_dir) -> dict[str, dict]:
    """{name: JSON document} of the studies the verdicts cite (``STUDIES``: the preparation
    study, ``make preparation``; <z> by counting rule, ``make zcount``), read from the default
    scale's figures directory (they are made at 1000 grains); absent ones left out."""
    root = scale_dirs(figures_dir)["default"]
    return {k: json.loads((root / f).read_text()) for k, f in STUDIES.items()
            if (root / f).exists()}


QUIET_WINDOW_DEG = QUIET_DEG.value  # the paper's Fig. 5 shows clusters this far before an onset



def _quiet_past(e: dict) -> int:
    """Runs whose first onset comes at or after the paper's window (the paper's Fig. 5 has quiet
    frames at theta - theta_m = -14.4 deg, so theta_m >= 14.4 deg; a run with no onset to the
    end of its tilt counts: it stayed quiet)."""
    if "n_runs_quiet_past" in e:
        return int(e["n_runs_quiet_past"])
    return sum(x is None or num(x) >= QUIET_WINDOW_DEG for x in e["per_run"]["theta_first_onset"])


def render_preparation(figures_dir) -> list[str]:
    """Markdown lines: the preparation study (``preparation.json`` of ``figures_dir``, written by
    ``make preparation``), one row per ensemble in two tables (failure and memory; what the
    history leaves in the pile); [] when the study has not been run."""
    p = Path(figures_dir) / "preparation.json"
    if not p.exists():
        return []
    doc = json.loads(p.read_text())
    n = doc["numbers"]
    given = [m for m in doc.get("ensembles", []) if "slide_ke" in (m.get("analysis") or {})]
    ke = num(n.get("slide_ke_reference"))
    threshold = (f"a kinetic energy per grain above {show(ke, '.1e')} (the study's slide_ke)" if given
                 else "the fresh piles' Fig. 2a kinetic-energy threshold")
    from_records = [m["label"] for m in doc.get("ensembles", []) if m.get("from_records")]
    records_note = ((" " if from_records else "")
                    + (f"Read from their records (no run files): {', '.join(from_records)}; the "
                       "pile at frame 0 (packing, fabric, surface) needs the run files' positions, "
                       "the repose angles `tiltpile repose` on the run files: n/a for "
                       f"{'it' if len(from_records) == 1 else 'them'}." if from_records else ""))

    def ci(e, key, fmt):
        m, lo, hi = (num(e.get(f"{key}_{x}")) for x in ("mean", "ci_low", "ci_high"))
        if not math.isfinite(m):
            return "n/a"
        return f"{m:{fmt}} [{lo:{fmt}}, {hi:{fmt}}]" if math.isfinite(lo) else f"{m:{fmt}}"

    def rep(e, key):
        r = (e.get("repose") or {}).get(key)
        if not r or not math.isfinite(num(r.get("estimate"))):
            return "n/a"
        lo, hi = num(r.get("low")), num(r.get("high"))
        band = f" [{lo:.1f}, {hi:.1f}]" if math.isfinite(lo) and math.isfinite(hi) else ""
        return f"{num(r['estimate']):.1f}{band} ({r.get('n')})"

    lines = ["", "## Which pile did the paper analyse? Preparation histories", "",
             "From `preparation.json` (`make preparation PREP_DIRS=...`): the same pile and ramp, piles "
             "tilted back and forth before the analysed ramp (`protocol.pretilt_deg`, or "
             "`protocol.cycles` and `protocol.theta_rev_deg` for Deboeuf et al.'s two cycles past "
             f"theta_rev) against fresh ones ({n['reference']}, the reference); mean [95% bootstrap "
             "interval over runs]. The paper's Fig. 5 needs runs whose first onset comes after "
             f"{QUIET_WINDOW_DEG:g} deg; Deboeuf et al. give theta_r ~ {REPOSE_DEG.value:g} deg and "
             f"theta_a ~ {AVALANCHE_DEG.value:g} deg "
             "for the paper's piles.", "",
             f"Slides in the ramp are detected at {threshold} "
             "for every ensemble. The slide and repose angles come from `tiltpile repose`, which "
             "tilts each finished run on into its large slide and back until the flow stops "
             "(runs measured in brackets); the repose angle is the box's angle then, and the slope "
             "of the free surface to the horizontal (lower: the slide has piled grains downhill). The memory: the first frame losing more than 0.5% of its "
             "contacts (irreversible change, however small) and the first 2% onset over the "
             "history's amplitude theta_rev." + records_note, "",
             f"| preparation | runs | first 2% onset (deg) | runs quiet past {QUIET_WINDOW_DEG:g} deg "
             "| first slide in the ramp (deg; runs) | slide angle (deg; repose) "
             "| repose angle: box (deg) | repose angle: surface (deg) "
             "| first change > 0.5% (deg) | first onset / theta_rev "
             "| onsets below theta_rev |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    best, best_n = None, -1
    for label, e in n["ensembles"].items():
        quiet = _quiet_past(e)
        if quiet > best_n:
            best, best_n = label, quiet
        slide = "theta_first_slide_ref_ke" if "theta_first_slide_ref_ke_mean" in e else "theta_first_slide"
        lines.append(
            f"| {label} | {e['n_runs']} | {ci(e, 'theta_first_onset', '.2f')} | {quiet} of {e['n_runs']} "
            f"| {ci(e, slide, '.2f')} ({e.get('n_runs_with_slide' + slide[len('theta_first_slide'):])}) "
            f"| {rep(e, 'slide_deg')} | {rep(e, 'stop_deg')} | {rep(e, 'surface_deg')} "
            f"| {ci(e, 'theta_first_change', '.2f')} "
            f"| {ci(e, 'onset_over_rev', '.2f')} | {ci(e, 'n_onsets_below_rev', '.2f')} |")
    lines += ["", "What the history leaves in the pile (frame 0, after it) and in the ramp's quiet "
              "frames:", "",
              "| preparation | <z> quiet | <n_m> quiet | packing fraction at 0 deg "
              "| fabric anisotropy at 0 deg | fabric major axis (deg from normal) "
              "| surface tilt at 0 deg | Fig. 2b Ashman D | frames losing no contact |",
              "|---|---|---|---|---|---|---|---|---|"]
    for label, e in n["ensembles"].items():
        bim = e.get("lost_bimodality") or {}
        lines.append(
            f"| {label} | {ci(e, 'z_quiet', '.3f')} | {ci(e, 'n_m_quiet', '.4f')} "
            f"| {ci(e, 'phi_start', '.4f')} | {ci(e, 'fabric_start', '.3f')} "
            f"| {ci(e, 'fabric_major_start', '.1f')} | {ci(e, 'surface_tilt_start', '.2f')} "
            f"| {show(num(bim.get('ashman_d')), '.2f')} "
            f"| {show(num(e.get('lost_zero_fraction')), '.0%')} |")
    ref = n["ensembles"][n["reference"]]
    lines.append("")
    if best_n > 0:
        lines.append(f"**{best}** brings the most runs past the paper's {QUIET_WINDOW_DEG:g} deg before their "
                     f"first onset ({best_n} of {n['ensembles'][best]['n_runs']}; fresh piles: "
                     f"{_quiet_past(ref)}).")
    else:
        lines.append(f"No preparation studied brings a run past {QUIET_WINDOW_DEG:g} deg before its first "
                     "onset; the differences from the fresh piles (first onset, onsets below the "
                     "preparation's amplitude) show how far each goes.")
    for label, dd in n.get("differences", {}).items():
        d = dd.get("theta_first_onset")
        if d:
            slide = _slide_difference(ref, n["ensembles"][label], dd)
            lines.append(f"- {label}: first onset {d['estimate']:+.2f} deg [{d['low']:+.2f}, {d['high']:+.2f}] "
                         f"against the fresh piles{slide}.")
    return lines


def _slide_difference(ref: dict, e: dict, dd: dict) -> str:
    """', first slide in the ramp +a deg [lo, hi]' when every run of both ensembles slid before
    the end of its tilt (a mean over the runs that slid would favour the early ones), else ''."""
    key = "theta_first_slide_ref_ke" if "theta_first_slide_ref_ke" in dd else "theta_first_slide"
    count = "n_runs_with_slide" + key[len("theta_first_slide"):]
    d = dd.get(key)
    if not d or any(x.get(count) != x.get("n_runs") for x in (ref, e)):
        return ""
    if not all(math.isfinite(num(d.get(k))) for k in ("estimate", "low", "high")):
        return ""
    return (f", first slide in the ramp {d['estimate']:+.2f} deg "
            f"[{d['low']:+.2f}, {d['high']:+.2f}]")


# ----------------------------------------------------------------------------------------------
# a parameter study (`tiltpile study`, `make study`)

STUDY_COLUMNS = (("theta_first_onset", "first 2% onset (deg)", ".2f"),
                 ("theta_avalanche", "avalanche angle (deg; runs)", ".2f"),
                 ("repose_surface", "repose: surface (deg)", ".2f"),
                 ("repose_box", "repose: box (deg)", ".2f"),
                 ("z_quiet", "<z> quiet", ".3f"),
                 ("n_m_quiet", "<n_m> quiet", ".4f"),
                 ("quiet_below", "quiet below z = 3 + n_m", ".3f"),
                 ("orientation", "cluster orientation (deg)", ".1f"),
                 ("delta", "delta", ".2f"),
                 ("s_max_near", "<S_max> near onset", ".1f"),
                 ("rigid_near", "rigid share near onset", ".3f"))


def render_study(doc: dict) -> list[str]:
    """Markdown lines of a parameter study's section, from its JSON (``study.json`` of
    ``tiltpile study``): how it was made, one row per value (mean [bootstrap interval over runs]
    of every number) and, for scene.mu, the Mohr-Coulomb test of the clusters' orientation."""
    n = doc["numbers"]
    st = doc.get("study", {})
    key = n["key"]
    hist = st.get("history") or "preset"
    how = (f"each value's piles cycled twice to its own fresh repose angle (surface) + "
           f"{st.get('history_offset_deg'):g} deg, rounded to the whole degree"
           if hist != "preset" else "the preset's own history")
    lines = ["", f"## Parameter study: {key} ({st.get('name', '')})", "",
             f"From `{st.get('command', 'tiltpile study')}`: preset {st.get('preset')}, "
             f"{len(n['labels'])} values of `{key}`, {st.get('runs')} run{'' if st.get('runs') == 1 else 's'} "
             f"each, {how}. Mean "
             f"[{100 * n['confidence']:g}% bootstrap interval over runs]; repose angles by "
             "`tiltpile repose` (" + ("fresh piles" if hist != "preset" else "the study's piles")
             + ").", ""]
    return lines + study_table(doc) + mohr_coulomb_lines(n.get("mohr_coulomb"))


def _cell(c: dict, fmt: str) -> str:
    m, lo, hi = (num(c.get(f)) for f in ("estimate", "low", "high"))
    if not math.isfinite(m):
        return "n/a"
    band = f" [{lo:{fmt}}, {hi:{fmt}}]" if math.isfinite(lo) and math.isfinite(hi) else ""
    extra = f" ({c['n_runs_with']})" if "n_runs_with" in c else ""
    return f"{m:{fmt}}{band}{extra}"


def study_table(doc: dict) -> list[str]:
    """Markdown rows of a study's table: one row per value, mean [interval] of every number."""
    n = doc["numbers"]
    key = n["key"]
    lines = [f"| {key} | runs | theta_rev (deg) | "
             + " | ".join(h for _, h, _ in STUDY_COLUMNS) + " |",
             "|---|---|---|" + "---|" * len(STUDY_COLUMNS)]
    for lab in n["labels"]:
        pv = n["per_value"][lab]
        rev = pv.get("theta_rev_deg")
        lines.append(f"| {lab} | {pv['n_runs']} | {'preset' if rev is None else f'{rev:g}'} | "
                     + " | ".join(_cell(pv["numbers"][k], f) for k, _, f in STUDY_COLUMNS) + " |")
    return lines


#: what the slope of the clusters' orientation against Mohr-Coulomb's angle says, per verdict
#: of :func:`tiltpile.analysis.mohr_coulomb.verdict`
MC_WORDS = {"consistent": "consistent with Mohr-Coulomb's slope 1",
            "flat": "consistent with no dependence on friction, not with Mohr-Coulomb's slope 1",
            "shallower": "below Mohr-Coulomb's slope 1 (and above 0)",
            "steeper": "above Mohr-Coulomb's slope 1",
            "undetermined": "undetermined (no interval: too few runs)"}


def mohr_coulomb_lines(mc: dict | None) -> list[str]:
    """The Mohr-Coulomb paragraph of a friction study (none for another key)."""
    if not mc:
        return []
    f = mc["fit"]
    pairs = "; ".join(f"mu = {m:g}: {show(num(y), '.1f')} against {p:.1f}"
                      for m, y, p in zip(mc["mu"], mc["measured_deg"], mc["predicted_deg"]))
    band = (f" [{f['slope_low']:.2f}, {f['slope_high']:.2f}]"
            if math.isfinite(num(f.get("slope_low"))) else "")
    return ["", "**Mohr-Coulomb.** The clusters' orientation to gravity (Fig. 3's: quiet "
            "clusters of >= 5 grains, pooled) against 45 + 1/2 atan(mu) deg: " + pairs
            + f". Least-squares slope of measured against predicted {show(num(f['slope']), '.2f')}"
            + band + f" (runs resampled within each value, {f['n_resamples']} resamples), "
            f"intercept {show(num(f['intercept']), '.1f')} deg: {MC_WORDS[mc['verdict']]}."]
