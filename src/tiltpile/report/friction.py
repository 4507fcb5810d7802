"""The report's section "Friction": the friction study (``make study KEY=scene.mu ...``, its JSON
``figures/study-friction/study.json``), the paper's Mohr-Coulomb reading of the clusters'
orientation tested across frictions, and the angles against what the literature reports for 2D
disk packings (``LITERATURE``).

The study's numbers and the Mohr-Coulomb fit are :mod:`tiltpile.figures.study`'s; this module
only words them. Its table and fit paragraph are the ones of the study's own section
(:func:`tiltpile.report.studies.study_table`, :func:`~tiltpile.report.studies.mohr_coulomb_lines`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from tiltpile.paper_values import AVALANCHE_DEG, ORIENTATION_DEG, REPOSE_DEG

from .judging import num, show
from .studies import mohr_coulomb_lines, study_table

#: the friction study's JSON, below the default scale's figures directory
STUDY = Path("study-friction") / "study.json"
KEY = "scene.mu"


@dataclass(frozen=True)
class Source:
    """A published number (or trend) on how 2D disk packings fail, to set beside ours."""
    cite: str
    system: str
    mu: float | None        # the contact friction, None where the source gives none
    quantity: str           # what the number is, in its source's terms
    theirs: str             # the value as the source gives it (angles in deg; "computed" marked)
    ours: str | None        # the study's number to compare with (a QUANTITIES key), if any
    why_not: str = ""       # where ``ours`` is None: why nothing of ours stands beside it


#: Each entry was read in its source's text (docs/friction-literature.md gives where, with the
#: sentence); angles computed here from a friction coefficient mu* as atan(mu*) are marked so.
LITERATURE = (
    Source("Deboeuf, Vilotte, Mangeney, Staron & Dauchot, book chapter (Taylor & Francis, 2005, "
           "doi:10.1201/NOE0415383486-27); the paper's piles",
           "2D, 4000 disks, Contact Dynamics, tilted at 0.001 deg per step", 0.5,
           "repose angle theta_r", f"~{REPOSE_DEG.value:g} deg", "repose_surface"),
    Source("the same", "the same", 0.5, "avalanche angle theta_a",
           f"~{AVALANCHE_DEG.value:g} deg", "theta_avalanche"),
    Source("Taboada, Chang, Radjai & Bouchette, J. Geophys. Res. (2005)",
           "2D, 5000 disks, Contact Dynamics, biaxial compression", None,
           "macroscopic friction (peak and residual) against contact friction",
           "rises nonlinearly with mu and saturates", "repose_surface"),
    Source("Frye & Marone, Geophys. Res. Lett. 29(19) (2002); Knuth & Marone, Geochem. "
           "Geophys. Geosyst. 8, Q03012 (2007)",
           "experiments: sheared layers of rods stacked in 2D (contact friction not given)", None,
           "effective friction mu* in stable sliding",
           "0.18-0.30 (10.2-16.7 deg, computed)", None,
           "a sheared layer under load, not a pile; no contact friction to place it at"),
    Source("Azema, Radjai & Roux, Phys. Rev. E 91, 010202(R) (2015)",
           "2D frictionless pentagons (not disks), slow shear", 0.0, "internal friction mu*",
           "0.183 +- 0.008 (10.4 deg, computed)", None,
           "pentagons; the frictionless limit, below our smallest mu"),
)


def load(figures_root) -> dict | None:
    """The friction study's JSON below the default scale's figures directory (None without it,
    or when it varies another key)."""
    p = Path(figures_root) / STUDY
    if not p.is_file():
        return None
    doc = json.loads(p.read_text())
    return doc if doc.get("numbers", {}).get("key") == KEY else None


def _estimate(doc: dict, label: str, key: str) -> float:
    pv = doc["numbers"]["per_value"].get(label)
    return num(pv["numbers"].get(key, {}).get("estimate")) if pv else math.nan


def _labels_by_mu(doc: dict) -> list[tuple[float, str]]:
    n = doc["numbers"]
    return sorted((float(n["per_value"][lab]["value"]), lab) for lab in n["labels"])


def _ours(doc: dict, src: Source) -> str:
    """Our number beside a source's: at its friction, or across all of ours for a trend."""
    if src.ours is None:
        return f"({src.why_not})"
    by_mu = _labels_by_mu(doc)
    if src.mu is not None:
        lab = next((lab for mu, lab in by_mu if math.isclose(mu, src.mu)), None)
        if lab is None:
            return f"(mu = {src.mu:g} not in the study)"
        v = _estimate(doc, lab, src.ours)
        if not math.isfinite(v):
            return f"none: no pile slid within the ramp (mu = {src.mu:g})"
        return f"{show(v, '.1f')} deg (mu = {src.mu:g})"
    return ", ".join(f"{show(_estimate(doc, lab, src.ours), '.1f')} (mu = {mu:g})"
                     for mu, lab in by_mu) + " deg"


def saturation(doc: dict, key: str) -> dict | None:
    """How an angle grows with friction: its rise from the smallest mu to 0.5 and from 0.5 to the
    largest (deg), when the study has all three and each has the angle; None otherwise."""
    by_mu = _labels_by_mu(doc)
    mid = next((lab for mu, lab in by_mu if math.isclose(mu, 0.5)), None)
    if mid is None or len(by_mu) < 3 or not by_mu[0][0] < 0.5 < by_mu[-1][0]:
        return None
    lo, hi = by_mu[0], by_mu[-1]
    a, b, c = (_estimate(doc, lab, key) for lab in (lo[1], mid, hi[1]))
    if not all(math.isfinite(x) for x in (a, b, c)):
        return None
    return {"mu_low": lo[0], "mu_high": hi[0], "rise_low": b - a, "rise_high": c - b}


def answer(mc: dict | None) -> str:
    """One plain sentence: does Mohr-Coulomb's reading of the orientation survive a change of
    friction in our piles."""
    if not mc:
        return "The study has no Mohr-Coulomb fit."
    f = mc["fit"]
    slope = (f"slope {show(num(f['slope']), '.2f')} [{show(num(f.get('slope_low')), '.2f')}, "
             f"{show(num(f.get('slope_high')), '.2f')}] against Mohr-Coulomb's 1")
    v = mc["verdict"]
    if v == "consistent":
        return (f"**The paper's Mohr-Coulomb reading survives a change of friction in our piles:** "
                f"the clusters' orientation follows 45 + 1/2 atan(mu) across mu = "
                f"{min(mc['mu']):g}-{max(mc['mu']):g} ({slope}).")
    if v == "undetermined":
        return "**Mohr-Coulomb across frictions is undetermined:** too few runs for an interval."
    how = {"flat": "does not move with friction", "shallower": "moves with friction, but less "
           "than Mohr-Coulomb's failure plane", "steeper": "moves with friction more than "
           "Mohr-Coulomb's failure plane"}[v]
    return (f"**The paper's Mohr-Coulomb reading does not survive a change of friction in our "
            f"piles:** the clusters' orientation {how} ({slope}), so their lean of "
            f"{show(_mc_at(mc, 0.5), '.0f')} deg at mu = 0.5 (the paper: ~{ORIENTATION_DEG.value:g}) "
            "is not explained by the failure plane's angle.")


def _mc_at(mc: dict, mu: float) -> float:
    for m, y in zip(mc["mu"], mc["measured_deg"]):
        if math.isclose(m, mu):
            return num(y)
    return math.nan


def render(doc: dict | None) -> list[str]:
    """Markdown lines of the section "Friction" (none without the study)."""
    if doc is None:
        return []
    n, st = doc["numbers"], doc.get("study", {})
    mc = n.get("mohr_coulomb")
    if st.get("history_offset_deg") is not None:
        amps = ", ".join(f"{lab}: {show(num(n['per_value'][lab].get('theta_rev_deg')), 'g')}"
                         for _, lab in _labels_by_mu(doc))
        history = ("Each friction's piles are cycled twice to their own fresh repose angle + "
                   f"{st['history_offset_deg']:g} deg, rounded to the degree (Deboeuf's cycles "
                   f"go past the repose angle at every friction); the amplitudes (deg): {amps}.")
    else:
        history = "Every friction's piles have the preset's own history."
    lines = ["", "## Friction", "",
             "The paper explains the clusters' orientation by Mohr-Coulomb: failure planes at "
             "45 + 1/2 atan(mu) deg to gravity, ~58 deg at mu = 0.5. One friction cannot test "
             "that; the friction study changes the grains' mu (grain on grain and on the "
             "fixed bottom row; the box's side walls keep `scene.mu_wall`) and nothing else "
             f"(`{st.get('command', 'tiltpile study')}`: preset {st.get('preset')}, "
             f"{st.get('runs')} piles of {_grains(doc)} grains per value). " + history, "",
             answer(mc), ""]
    lines += study_table(doc) + mohr_coulomb_lines(mc)
    lines += ["", "**What the literature reports** for 2D disk packings (sources and the "
              "sentences read: docs/friction-literature.md):", "",
              "| source | system | mu | quantity | theirs | ours |", "|---|---|---|---|---|---|"]
    for s in LITERATURE:
        lines.append(f"| {s.cite} | {s.system} | {'-' if s.mu is None else f'{s.mu:g}'} | "
                     f"{s.quantity} | {s.theirs} | {_ours(doc, s)} |")
    sat = [(k, saturation(doc, k)) for k in ("repose_surface", "theta_avalanche")]
    words = {"repose_surface": "repose angle", "theta_avalanche": "avalanche angle"}
    said = [f"the {words[k]} changes by {show(s['rise_low'], '+.1f')} deg from mu = "
            f"{s['mu_low']:g} to 0.5 and by {show(s['rise_high'], '+.1f')} deg from 0.5 to "
            f"{s['mu_high']:g}" for k, s in sat if s]
    slid = _slid(doc)
    if slid and not dict(sat)["theta_avalanche"]:
        said.append(f"the avalanche angle is out of the ramp's reach: {slid[0]} of {slid[1]} "
                    "piles slid before its end")
    if said:
        lines += ["", "In our piles " + "; ".join(said) + f". Our angles are at {_grains(doc)} "
                  "grains, Deboeuf's at 4000; no published measurement of the failing "
                  "clusters' orientation against friction was found."]
    return lines


def _slid(doc: dict) -> tuple[int, int] | None:
    """(piles that slid within the ramp, piles) over every value of the study."""
    pv = doc["numbers"]["per_value"].values()
    ava = [v["numbers"].get("theta_avalanche") for v in pv]
    if any(a is None or "n_runs_with" not in a for a in ava):
        return None
    return sum(int(a["n_runs_with"]) for a in ava), sum(int(v["n_runs"]) for v in pv)


def _grains(doc: dict) -> str:
    g = sorted({str(e.get("n_grains")) for e in doc.get("ensembles", []) if e.get("n_grains")})
    return "/".join(g) if g else "?"
