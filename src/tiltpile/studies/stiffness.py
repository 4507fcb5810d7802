"""The second engine in its rigid limit (issue 73, items 1, 3 and 4): which of the soft-sphere
DEM's numbers and verdicts move with its stiffness, where they go as the contacts become rigid,
and what a stiffer DEM costs.

One ensemble of the study's DEM preset (``default-dem``: the default preset's 1000-grain piles,
history and ramp) per stiffness (``SETTINGS``): the preset's k_n (the committed setting,
``reference``), 4 k_n with ``dem.dt`` / 2 and 16 k_n with ``dem.dt`` / 4, each a two-key override
``dem.kn``, ``dem.dt`` of the preset's values (so a collision spans as many steps at every
stiffness: the contact time goes as 1 / sqrt(k_n)). A stiffness whose time step would be too long
for it (``config.dem_contact_steps`` below ``config.DEM_MIN_CONTACT_STEPS``) is refused by the
configuration before anything runs. The stiffest setting runs half the piles (``share``): 6, 6 and
3 piles of seeds 0, 1, ... for ``runs`` = 6. Per stiffness:

* **its numbers** (:func:`measures_on`; ``MEASURES``): <z> and <n_m> of the quiet frames and the
  first 2% onset (per pile, as ``tiltpile same-piles`` reads them: their mean over the piles and
  its standard error), and Fig. 2b's two populations of the lost fraction as the report reads
  them (:func:`tiltpile.report.blocks.populations`: where the upper one sits, and how much of it
  lies below the 2% cutoff; their standard error by the jackknife over piles, from 3 piles on);
* **every claim's verdict** (the report's judges on its figures), and whether a stiffer setting
  *flips* a claim: its verdict on the same piles differs from the committed setting's (the
  solver study's comparison, :func:`tiltpile.studies.settings.compare_settings`: pile against
  pile and every figure number in units of its jackknife error);
* **the engines** (:func:`analyse` with ``cd_dir``): the setting against Contact Dynamics'
  records of the same seeds (the default preset's; the same piles: Contact Dynamics deposits
  the DEM's piles), pile against pile and claim by claim, where those records exist;
* **its cost**: DEM steps and core-hours per run (the records' costs), and with ``paper_dir``
  (the committed records of the DEM at the paper's scale, paper-5x-dem's, at the preset's k_n)
  what one run and a 50-pile ensemble there would cost at this stiffness (the paper-scale runs'
  cost times this stiffness' steps per run over the reference's: the cost of a DEM step is set
  by the grains, the steps by the time step);
* **its health stops** as in the solver study: a failed setting, listed with its rule.

**Against 1 / k_n.** Each number is followed against x = k_n(reference) / k_n (1, 1/4, 1/16: the
overlap scale m g / k_n in units of the reference's), on the seeds every stiffness holds (the
*fit seeds*; a per-pile number on those where every stiffness has it), and extrapolated to the
rigid limit x -> 0 by a straight line (:func:`extrapolate`, weights 1 / error^2), where the trend
allows it: at least ``MIN_POINTS`` = 3 stiffnesses with the number and its error; monotone (no
two steps between neighbouring stiffnesses of opposite signs, each beyond ``SIGMA_LIMIT`` = 2 of
its error); and straight (the residual at every stiffness within ``SIGMA_LIMIT`` of its error).
Otherwise the number "does not extrapolate", with the reason. The stiffnesses share their piles,
so the errors of the steps, the residuals and the limit are the jackknife's over the piles (one
pile left out of every stiffness at once): the spread from pile to pile that every stiffness
shares cancels from the steps and residuals, and enters the limit's error as it should. A
point's error bar is the standard error over the piles (Fig. 2b's populations: the jackknife's).
Beside the limit, Contact Dynamics' number on the same piles, and the limit minus it with the
jackknife error of that difference.

**Per claim** (:func:`claims_numbers`): across the stiffnesses, the same verdict at every k_n,
*flips* at which k_n, or undecided (a stiffness not compared yet, or a verdict inconclusive);
and against Contact Dynamics on the same piles: the same verdict in both engines at every k_n,
the same from some k_n on (the difference goes away as the contacts stiffen), different at every
k_n (the difference survives to the stiffest), different from some k_n on, or undecided.

Outputs (:func:`write`): ``FIGURES/stiffness_study.{json,png,pdf}`` (every setting's numbers,
the fits, the claims; the figure: each number against x with its fit and Contact Dynamics') and
``FIGURES/stiffness_study.md`` (:func:`render`, the report section "The second engine in its
rigid limit"). Comparisons are kept below ``FIGURES/same-piles/``: ``<setting>/`` (against the
committed setting), ``cd/<setting>/`` (against Contact Dynamics), ``reference/`` and
``own/<setting>/`` (a side's figures), ``measures/<label>_<seeds>/`` (the numbers above), each
with the digest of its inputs and reused while it holds.

The command is ``tiltpile stiffness-study`` (:mod:`tiltpile.cli.stiffness_study`).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

from tiltpile import config as cfgmod

from .settings import (COMPARISONS, INPUTS, REFERENCE, Plan, check_preset, check_runs,  # noqa: F401
                       code_digest, compare, compare_settings, configure, cost, documents,
                       fingerprint, fmt, health_stops, load_side, num, read_runs, recorded, seeds_text,
                       setting_entry, shift, shift_text, stops_text, verdicts)

NAME = "stiffness_study"
SECTION = "The second engine in its rigid limit"
#: the label of Contact Dynamics' side in the comparisons
CD = "cd"
AXIS = "stiffness"
FIG2 = "fig2_avalanche_criterion"
#: the fewest stiffnesses a number is extrapolated from
MIN_POINTS = 3
#: a 50-pile ensemble at the paper's scale: the runs the issue prices
PAPER_RUNS = 50
#: below FIGURES/same-piles/: a side's figures on its seeds, the comparisons with Contact
#: Dynamics, the numbers of a side on some seeds
OWN, MEASURES_DIR = "own", "measures"
#: the layout of a kept measures.json (:func:`measures_on`), part of its inputs' digest
MEASURES_FORMAT = "tiltpile-stiffness-measures/1"


@dataclass(frozen=True)
class Measure:
    """A number the study follows against the stiffness (``key``: its name in the per-pile table
    of ``same_piles.per_seed``, or of ``report.blocks.populations``)."""
    key: str
    label: str
    unit: str
    scale: float      # printed as value x scale
    spec: str         # printed with this format
    per_seed: bool    # a per-pile number (mean over piles) or Fig. 2's ensemble number
    short: str        # the figure's axis label


MEASURES = (
    Measure("z_quiet", "<z>, quiet frames", "", 1.0, ".4f", True, "<z>"),
    Measure("n_m_quiet", "<n_m>, quiet frames", "", 1.0, ".4f", True, "<n_m>"),
    Measure("theta_first_onset", "first 2% onset", "deg", 1.0, ".2f", True, "first onset [deg]"),
    Measure("upper", "upper population of the lost fraction (its mean)", "%", 100.0, ".2f", False,
            "upper population [% lost]"),
    Measure("upper_below", "share of the upper population below the 2% cutoff", "%", 100.0, ".0f",
            False, "upper population below 2% [%]"),
)
_SHORT = {m.key: m.short for m in MEASURES}
#: the pile-against-pile numbers given against Contact Dynamics
ENGINE_KEYS = ("z_quiet", "n_m_quiet", "theta_first_onset")


@dataclass(frozen=True)
class Stiffness:
    """One setting: ``name`` (its directory and label), k_n as ``factor`` times the preset's and
    ``dem.dt`` as the preset's over ``divisor``, ``share`` of the study's runs (rounded up, at
    least 2), and its ``overrides`` (``dem.kn=...``, ``dem.dt=...``; :func:`plan` writes them from
    the preset's values; none for the committed setting)."""
    name: str
    factor: float
    divisor: float
    share: float = 1.0
    overrides: tuple[str, ...] = ()

    @property
    def axis(self) -> str:
        return "committed" if self.name == REFERENCE else AXIS


#: the study's settings, the committed one first, in the order their ensembles run (issue 73
#: item 1: 6 piles at k_n and 4 k_n, 3 at 16 k_n)
SETTINGS: tuple[Stiffness, ...] = (Stiffness(REFERENCE, 1.0, 1.0), Stiffness("4kn_dt2", 4.0, 2.0),
                                   Stiffness("16kn_dt4", 16.0, 4.0, share=0.5))

_STIFF_RE = re.compile(r"(\d+(?:\.\d+)?)kn_dt(\d+(?:\.\d+)?)")


def _g(x: float) -> str:
    return f"{x:g}"


def stiffness(text: str) -> Stiffness:
    """A setting of ``SETTINGS`` by name, else the setting named ``<F>kn_dt<D>``: F times the
    preset's k_n at its dem.dt over D (all the runs)."""
    by_name = {s.name: s for s in SETTINGS}
    t = text.strip()
    if t in by_name:
        return by_name[t]
    m = _STIFF_RE.fullmatch(t)
    if not m:
        raise cfgmod.ConfigError(f"--only {t!r}: neither a setting of the study "
                                 f"({', '.join(by_name)}) nor <F>kn_dt<D> (F times the preset's "
                                 "k_n at its dem.dt over D, e.g. 8kn_dt3)")
    factor, divisor = float(m.group(1)), float(m.group(2))
    if factor <= 0 or divisor <= 0:
        raise cfgmod.ConfigError(f"--only {t}: the factor and the divisor must be positive")
    return Stiffness(f"{_g(factor)}kn_dt{_g(divisor)}", factor, divisor)


def runs_of(s: Stiffness, runs: int) -> int:
    """The runs of a setting: its share of ``runs``, rounded up, at least 2 (a comparison needs
    two piles), at most ``runs``."""
    from tiltpile.figures import same_piles as sp

    return min(runs, max(sp.MIN_SEEDS, math.ceil(runs * s.share - 1e-9)))


def plan(preset: str = "default-dem", base=(), only=None, runs: int = 6) -> Plan:
    """The validated plan: the preset with ``base`` (a DEM configuration: a ``[dem]`` section),
    each setting's ``dem.kn`` and ``dem.dt`` written from its values (``Stiffness.overrides``), its
    configuration loaded (``config.load``: a time step too long for the stiffness is refused
    there) and its seeds 0 .. :func:`runs_of` - 1. ConfigError (one line naming the setting, the
    key or the value) for an unknown preset, setting, key or value, a configuration without a
    DEM, ``runs`` < 1, a setting named twice or one whose configuration is another's. ``only``:
    names of ``SETTINGS`` or ``<F>kn_dt<D>`` (None: every setting); the committed setting is
    always planned."""
    check_runs(runs)
    check_preset(preset)
    base = tuple(base)
    try:
        cfg = cfgmod.load(preset, None, base)
    except cfgmod.ConfigError as e:
        raise cfgmod.ConfigError(f"--set: {e}") from None
    if cfg.dem is None:
        raise cfgmod.ConfigError(f"--preset {preset}: a Contact Dynamics configuration (no [dem] "
                                 "section): the stiffness study varies the DEM's k_n; give a DEM "
                                 "preset (default-dem) or --set dem.kn=...")
    chosen = list(SETTINGS) if only is None else [SETTINGS[0]] + [stiffness(t) for t in only
                                                                  if t.strip() != REFERENCE]
    if only is not None and len(chosen) < 2:
        raise cfgmod.ConfigError("--only: name at least one setting besides the reference")
    kn, dt = cfg.dem.kn, cfg.dem.dt
    chosen = [s if s.name == REFERENCE else
              replace(s, overrides=(f"dem.kn={kn * s.factor!r}", f"dem.dt={dt / s.divisor!r}"))
              for s in chosen]
    return Plan(preset, base, runs, configure(preset, base, chosen, lambda s: range(runs_of(s, runs))))


def cd_config(the_plan: Plan) -> cfgmod.Config:
    """Contact Dynamics' configuration of the study's piles: the committed setting's without
    its ``[dem]`` section (default-dem's is the default preset's)."""
    return replace(the_plan.reference.config, dem=None)


def cd_preset(preset: str) -> str:
    """The preset Contact Dynamics' side is described as: a DEM preset's Contact Dynamics twin
    (``default-dem``: ``default``), else the preset itself (its figures' documents name it)."""
    twin = preset.removesuffix("-dem")
    return twin if twin != preset and twin in cfgmod.PRESETS else preset


# ----------------------------------------------------------------------------------------------
# the extrapolation to the rigid limit


def jackknife_se(values) -> float:
    """Jackknife standard error from leave-one-out values: sqrt((n - 1) / n sum (t_i - mean)^2);
    NaN for fewer than 2 or a value that is not finite."""
    t = [num(v) for v in values]
    if len(t) < 2 or not all(math.isfinite(v) for v in t):
        return math.nan
    m = sum(t) / len(t)
    return math.sqrt((len(t) - 1) / len(t) * sum((v - m) ** 2 for v in t))


def extrapolate(x, y, err, *, loo=None, sigma: float | None = None,
                min_points: int = MIN_POINTS) -> dict:
    """The straight line through the points (x, y) of errors ``err`` (weights 1 / err^2; all
    errors 0: equal weights), read at x = 0, where the trend allows it (module docstring): at
    least ``min_points`` distinct x with a finite y and a finite error; no two steps between
    neighbours in x of opposite signs, each beyond ``sigma`` of its error; every residual within
    ``sigma`` of its error (round-off aside).

    The errors of the steps, the residuals and the limit: propagated from ``err`` (independent
    points), or with ``loo`` (the points' values on the same piles, one list per pile left out:
    the points share their piles) by the jackknife over the piles of each of them, the line's
    weights held fixed.

    Returns {status: "extrapolated" | "too few stiffnesses" | "no error" | "not monotone" |
    "not linear", reason (None when extrapolated), value and error (the line at 0 and its error;
    NaN unless extrapolated), slope, slope_error, residuals and residual_errors (sorted by x; of
    the fit tried), value_loo (the limit leaving out each pile, with ``loo``), n}."""
    from tiltpile.figures import same_piles as sp

    sigma = sp.SIGMA_LIMIT if sigma is None else sigma
    keep = sorted((i for i in range(len(x)) if math.isfinite(num(x[i])) and math.isfinite(num(y[i]))),
                  key=lambda i: num(x[i]))
    xs, ys, es = [num(x[i]) for i in keep], [num(y[i]) for i in keep], [num(err[i]) for i in keep]
    reps = None if loo is None else [[num(r[i]) for i in keep] for r in loo]
    out = {"status": "extrapolated", "reason": None, "value": math.nan, "error": math.nan,
           "slope": math.nan, "slope_error": math.nan, "residuals": [], "residual_errors": [],
           "value_loo": [], "n": len(keep)}
    distinct = len(set(xs))
    if distinct < min_points:
        return dict(out, status="too few stiffnesses",
                    reason=f"{distinct} stiffness{'es' if distinct != 1 else ''} with the number; "
                           f"the line needs {min_points}")
    if not all(math.isfinite(e) and e >= 0 for e in es) or (reps is not None and len(reps) < 2):
        return dict(out, status="no error", reason="a stiffness' number has no error (too few piles)")
    tiny = 1e-9 * max(1.0, max(abs(v) for v in ys))      # round-off

    def se(f):
        """The error of a linear statistic f of the points' values."""
        if reps is None:
            return None
        return jackknife_se([f(r) for r in reps])

    steps = []
    for j in range(len(xs) - 1):
        d = ys[j + 1] - ys[j]
        e = se(lambda v, j=j: v[j + 1] - v[j])
        e = math.hypot(es[j], es[j + 1]) if e is None else e
        steps.append((d, e))
    if any(not math.isfinite(e) for _, e in steps):
        return dict(out, status="no error", reason="a stiffness' number has no error (too few piles)")
    signs = {d > 0 for d, e in steps if abs(d) > sigma * e + tiny}
    if len(signs) > 1:
        return dict(out, status="not monotone",
                    reason=f"it rises and falls between stiffnesses by more than {sigma:g} errors")
    floor = max(min((e for e in es if e > 0), default=1.0) * 1e-6, 1e-300)
    w = [1.0 / max(e, floor) ** 2 for e in es] if any(e > 0 for e in es) else [1.0] * len(es)
    sw, sx, sxx = sum(w), sum(a * b for a, b in zip(w, xs)), sum(a * b * b for a, b in zip(w, xs))
    det = sw * sxx - sx * sx
    ca = [wi * (sxx - sx * xi) / det for wi, xi in zip(w, xs)]
    cb = [wi * (sw * xi - sx) / det for wi, xi in zip(w, xs)]

    def line(v):
        return sum(c * t for c, t in zip(ca, v)), sum(c * t for c, t in zip(cb, v))

    def resid(v, k):
        a, b = line(v)
        return v[k] - (a + b * xs[k])

    a0, b0 = line(ys)
    res = [resid(ys, k) for k in range(len(xs))]
    if reps is None:
        a_err = math.sqrt(sum((c * e) ** 2 for c, e in zip(ca, es)))
        b_err = math.sqrt(sum((c * e) ** 2 for c, e in zip(cb, es)))
        r_err = list(es)
    else:
        a_err, b_err = se(lambda v: line(v)[0]), se(lambda v: line(v)[1])
        r_err = [se(lambda v, k=k: resid(v, k)) for k in range(len(xs))]
    out.update(value=a0, error=a_err, slope=b0, slope_error=b_err, residuals=res,
               residual_errors=r_err, value_loo=[] if reps is None else [line(r)[0] for r in reps])
    if not all(math.isfinite(e) for e in r_err):
        return dict(out, status="no error", value=math.nan, error=math.nan,
                    reason="a stiffness' number has no error (too few piles)")
    bad = [k for k in range(len(xs)) if abs(res[k]) > sigma * r_err[k] + tiny]
    if bad:
        k = max(bad, key=lambda i: abs(res[i]) / max(r_err[i], floor))
        return dict(out, status="not linear", value=math.nan, error=math.nan,
                    reason=f"the line misses x = {xs[k]:g} by {abs(res[k]):.3g}, more than "
                           f"{sigma:g} of its error {r_err[k]:.3g}")
    return out


# ----------------------------------------------------------------------------------------------
# a side's numbers on some seeds


def _tag(seeds) -> str:
    s = sorted(int(x) for x in seeds)
    if s and s == list(range(s[0], s[-1] + 1)):
        return f"{s[0]}-{s[-1]}"
    return ".".join(map(str, s))


def measures_on(rec_dir, seeds, out_dir, preset: str, *, code: str, label: str, fig2=None,
                notebooks_dir="notebooks", workers: int = 1, progress=None) -> dict:
    """``MEASURES`` of the records ``rec_dir`` on ``seeds``: {seeds, per_seed: {key: [per pile]},
    values, errors, n: {key: ...}, loo: {key: [leaving out each pile] or None}}. The per-pile
    numbers (``same_piles.per_seed``, with Fig. 2's first onsets) by their mean over the piles
    that have one and its standard error (sd / sqrt(n), NaN below 2); Fig. 2's populations
    (``report.blocks.populations``) on all the piles, their values leaving out each pile and
    their jackknife error (NaN below ``same_piles.JACKKNIFE_SEEDS`` piles).
    ``fig2``: Fig. 2's document on these seeds if it is at hand. Kept in ``out_dir`` with its
    inputs' digest, and reused while it holds."""
    import numpy as np

    from tiltpile.figures import same_piles as sp
    from tiltpile.figures import style
    from tiltpile.report.blocks import populations

    out = Path(out_dir)
    fp = dict(fingerprint(code, {label: rec_dir}, seeds, 0), format=MEASURES_FORMAT)
    try:
        if json.loads((out / INPUTS).read_text()) == fp:
            return json.loads((out / "measures.json").read_text())
    except (OSError, ValueError):
        pass
    seeds = [int(s) for s in seeds]
    ens = load_side(rec_dir, preset, seeds)
    if fig2 is None:
        if progress:
            progress(f"{label}: Fig. 2 on seeds {seeds_text(seeds)}")
        fig2 = sp.figure_documents(ens, (FIG2,), notebooks_dir)[FIG2]
    table = sp.per_seed(ens, fig2["numbers"])
    doc = {"seeds": seeds, "per_seed": {}, "values": {}, "errors": {}, "n": {}}
    for m in MEASURES:
        if not m.per_seed:
            continue
        v = table[m.key].to_numpy(float)
        doc["per_seed"][m.key] = v.tolist()
        f = v[np.isfinite(v)]
        doc["values"][m.key] = float(f.mean()) if f.size else math.nan
        doc["errors"][m.key] = float(f.std(ddof=1) / math.sqrt(f.size)) if f.size >= 2 else math.nan
        doc["n"][m.key] = int(f.size)
    pop_keys = [m.key for m in MEASURES if not m.per_seed]
    pops = populations(fig2["numbers"])
    full = {k: num(pops.get(k)) for k in pop_keys}
    doc["values"].update(full)
    errors = {k: math.nan for k in pop_keys}
    doc["loo"] = {k: None for k in pop_keys}
    if len(seeds) >= sp.JACKKNIFE_SEEDS:
        jobs = ((f"{label}: Fig. 2 leaving out seed {s}" if progress else None,
                 sp.subset(ens, [t for t in seeds if t != s])) for s in seeds)
        loo = [{k: num(populations(d[FIG2]["numbers"]).get(k)) for k in pop_keys}
               for d in sp.documents_each(jobs, (FIG2,), notebooks_dir, workers, progress)]
        errors = {k: jackknife_se([v[k] for v in loo]) if math.isfinite(full[k]) else math.nan
                  for k in pop_keys}
        doc["loo"] = {k: [v[k] for v in loo] for k in pop_keys}
    doc["errors"].update(errors)
    doc["n"].update({k: len(seeds) if math.isfinite(full[k]) else 0 for k in pop_keys})
    doc = style.jsonable(doc)
    (out / INPUTS).unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    style.write_json(out / "measures.json", doc)
    style.write_json(out / INPUTS, fp)
    return json.loads((out / "measures.json").read_text())


# ----------------------------------------------------------------------------------------------
# the study's numbers


def dem_numbers(p) -> dict:
    """The setting's contact model: k_n, dt, their ratios to the committed setting's
    (``factor``, ``divisor``), x = 1 / factor (the overlap scale), 1 / k_n and the steps a
    collision of the two smallest grains spans."""
    c = p.config
    return {"kn": c.dem.kn, "dt": c.dem.dt, "factor": p.setting.factor,
            "divisor": p.setting.divisor, "x": 1.0 / p.setting.factor, "inv_kn": 1.0 / c.dem.kn,
            "contact_steps": cfgmod.dem_contact_steps(c)}


def _decisive(v) -> bool:
    from tiltpile.report.judging import AGREES, DISAGREES

    return v in (AGREES, DISAGREES)


def engines_summary(comparison: dict, name: str) -> dict:
    """A setting against Contact Dynamics on the same piles: the seeds, the figure numbers moved,
    the pile-against-pile shifts (DEM minus CD) of ``ENGINE_KEYS``, both sides' Fig. 2
    populations, both sides' verdicts and the claims whose verdicts differ."""
    from tiltpile.report.blocks import populations

    docs = comparison["documents"]
    dem, cd = verdicts(docs[name]), verdicts(docs[CD])
    pp = comparison["pile_against_pile"]
    return {"seeds": comparison["seeds"], "n_moved": comparison["n_moved"],
            "n_with_error": comparison["n_with_error"],
            "shifts": {k: shift(pp, k) for k in ENGINE_KEYS if k in pp["difference"]},
            "populations": {CD: populations(docs[CD][FIG2]["numbers"]),
                            "dem": populations(docs[name][FIG2]["numbers"])},
            "verdicts": {k: {CD: cd[k]["verdict"], "dem": dem[k]["verdict"]} for k in cd},
            "different": [k for k in cd if _decisive(cd[k]["verdict"])
                          and _decisive(dem.get(k, {}).get("verdict"))
                          and cd[k]["verdict"] != dem[k]["verdict"]]}


def paper_scale(paper_cost: dict | None, ref_cost: dict, c: dict) -> dict | None:
    """What a run and a ``PAPER_RUNS``-pile ensemble of the DEM at the paper's scale would cost at
    this stiffness: the paper-scale records' steps and core-hours per run times this setting's
    steps per run over the committed setting's (measured at the study's scale)."""
    if not paper_cost or paper_cost.get("steps_per_run") is None:
        return None
    a, b = num(c.get("steps_per_run")), num(ref_cost.get("steps_per_run"))
    if not (math.isfinite(a) and math.isfinite(b) and b > 0):
        return None
    ratio = a / b
    ch = num(paper_cost.get("core_hours_per_run"))
    return {"steps_ratio": ratio, "steps_per_run": paper_cost["steps_per_run"] * ratio,
            "core_hours_per_run": ch * ratio, "runs": PAPER_RUNS,
            "core_hours": PAPER_RUNS * ch * ratio}


def _sequence_outcome(same: list[bool], factors: list[float]) -> tuple[str, float | None]:
    """(outcome, from which factor) of the engines' agreement at increasing stiffness."""
    if all(same):
        return "same", None
    if not any(same):
        return "different", None
    k = same.index(not same[0])
    if all(v == same[k] for v in same[k:]):
        return ("same_from" if same[k] else "different_from"), factors[k]
    return "undecided", None


def claims_numbers(settings: list[dict], cd_available: bool) -> list[dict]:
    """Per claim of the report: its verdict at each stiffness (on its own piles), whether a
    stiffer setting flips it on the same piles (``stiffness``: outcome "same" | "flips" |
    "undecided", with the flips), and against Contact Dynamics on the same piles at each
    stiffness (``engines``: outcome "same" | "same_from" | "different" | "different_from" |
    "undecided", ``from``: the factor where it starts, the reason when undecided), and
    ``shared_disagreement``: Contact Dynamics disagrees with the paper and so does the DEM at the
    stiffest k_n, with the engines the same there and from some k_n on (the claims for which "the
    disagreement is not our engine's" holds in the rigid limit)."""
    from tiltpile.report.claims import CLAIMS
    from tiltpile.report.judging import DISAGREES

    live = sorted((s for s in settings if s["status"] != "failed"), key=lambda s: s["dem"]["factor"])
    out = []
    for c in CLAIMS:
        per = []
        for s in live:
            own = (s["own_verdicts"] or {}).get(c.key)
            ref = (s["verdicts"] or {}).get(c.key) if not s["committed"] else None
            eng = (s["engines"] or {}).get("verdicts", {}).get(c.key) if s["engines"] else None
            per.append({"name": s["name"], "factor": s["dem"]["factor"], "verdict": own,
                        "reference_same_piles": None if ref is None else ref["reference"],
                        "setting_same_piles": None if ref is None else ref["setting"],
                        "cd": None if eng is None else eng[CD],
                        "dem_same_piles": None if eng is None else eng["dem"]})
        others = [p for p in per if p["name"] != REFERENCE]
        flips = [p for p in others if p["setting_same_piles"] is not None
                 and "not measured" not in (p["reference_same_piles"], p["setting_same_piles"])
                 and p["reference_same_piles"] != p["setting_same_piles"]]
        if flips:
            stiff = {"outcome": "flips", "reason": None}
        elif not others or any(p["setting_same_piles"] is None for p in others):
            stiff = {"outcome": "undecided", "reason": "not every stiffness compared yet"}
        elif not all(_decisive(p["reference_same_piles"]) and _decisive(p["setting_same_piles"])
                     for p in others):
            stiff = {"outcome": "undecided", "reason": "inconclusive at some k_n"}
        else:
            stiff = {"outcome": "same", "reason": None}
        stiff["flips"] = [{"name": p["name"], "factor": p["factor"],
                           "reference": p["reference_same_piles"], "setting": p["setting_same_piles"]}
                          for p in flips]
        eng = {"outcome": "undecided", "from": None, "reason": None}
        if not cd_available:
            eng["reason"] = "Contact Dynamics' records of these seeds are not at hand"
        elif not per or any(p["cd"] is None for p in per):
            eng["reason"] = "not every stiffness compared with Contact Dynamics yet"
        elif not all(_decisive(p["cd"]) and _decisive(p["dem_same_piles"]) for p in per):
            eng["reason"] = "inconclusive at some k_n"
        else:
            outcome, start = _sequence_outcome([p["cd"] == p["dem_same_piles"] for p in per],
                                               [p["factor"] for p in per])
            eng.update(outcome=outcome, reason=None if outcome != "undecided"
                       else "the engines agree and differ by turns as k_n grows")
            eng["from"] = start
        last = per[-1] if per else None
        shared = bool(last and eng["outcome"] in ("same", "same_from") and last["cd"] == DISAGREES
                      and last["dem_same_piles"] == DISAGREES)
        out.append({"key": c.key, "text": c.text, "figure": c.figure, "per_setting": per,
                    "stiffness": stiff, "engines": eng, "shared_disagreement": shared})
    return out


def _paired(fit_names, fit_measures: dict, cd_measures: dict | None, m: Measure):
    """(y, err, loo, cd, cd_loo, seeds) of one number on the fit seeds: per stiffness its value,
    error and values leaving out each pile; Contact Dynamics' value and its values leaving out
    each pile (None without); the piles used. A per-pile number on the piles where every
    stiffness has it (its mean over them; leaving one out, the mean of the others); Fig. 2's
    populations as :func:`measures_on` gives them."""
    import numpy as np

    seeds = fit_measures[fit_names[0]]["seeds"]
    if m.per_seed:
        table = np.array([[num(v) for v in fit_measures[n]["per_seed"][m.key]] for n in fit_names], float)
        use = np.isfinite(table).all(axis=0)
        t = table[:, use]
        used = [s for s, u in zip(seeds, use) if u]
        k = t.shape[1]
        y = t.mean(axis=1).tolist() if k else [math.nan] * len(fit_names)
        loo = [np.delete(t, i, axis=1).mean(axis=1).tolist() for i in range(k)] if k >= 2 else None
        err = [jackknife_se([r[j] for r in loo]) for j in range(len(fit_names))] if loo else \
              [math.nan] * len(fit_names)
        cd = cd_loo = None
        if cd_measures is not None:
            c = np.array([num(v) for v in cd_measures["per_seed"][m.key]], float)[use]
            f = c[np.isfinite(c)]
            cd = float(f.mean()) if f.size else math.nan
            if k >= 2 and np.isfinite(c).all():
                cd_loo = [float(np.delete(c, i).mean()) for i in range(k)]
        return y, err, loo, cd, cd_loo, used
    y = [num(fit_measures[n]["values"].get(m.key)) for n in fit_names]
    err = [num(fit_measures[n]["errors"].get(m.key)) for n in fit_names]
    reps = [fit_measures[n].get("loo", {}).get(m.key) for n in fit_names]
    loo = [list(r) for r in zip(*reps)] if all(reps) else None
    cd = None if cd_measures is None else num(cd_measures["values"].get(m.key))
    cd_loo = None if cd_measures is None else cd_measures.get("loo", {}).get(m.key)
    return y, err, loo, cd, cd_loo, list(seeds)


def measures_numbers(fit_names, fit_measures: dict, cd_measures: dict | None,
                     by_name: dict) -> list[dict]:
    """Per ``MEASURES`` number: its points against x on the fit seeds (one per stiffness: value,
    error, the piles), the fit (:func:`extrapolate` with the values leaving out each pile: the
    stiffnesses share their piles), Contact Dynamics' number on the same piles, and the rigid
    limit and the stiffest k_n each against it (difference; its error by the jackknife over the
    same piles where both have the values leaving out each, else the errors combined; in
    errors)."""
    out = []
    for m in MEASURES:
        y, err, loo, cd_v, cd_loo, used = _paired(fit_names, fit_measures, cd_measures, m)
        pts = []
        for j, name in enumerate(fit_names):
            d = by_name[name]["dem"]
            pts.append({"name": name, "factor": d["factor"], "x": d["x"], "inv_kn": d["inv_kn"],
                        "value": y[j], "error": err[j], "n": len(used)})
        fit = extrapolate([p["x"] for p in pts], y, err, loo=loo)
        cd = (None if cd_v is None else
              {"value": cd_v, "error": jackknife_se(cd_loo) if cd_loo else
               num(cd_measures["errors"].get(m.key)), "n": len(used)})

        def against(v, e, v_loo):
            if cd is None or not (math.isfinite(num(v)) and math.isfinite(cd["value"])):
                return None
            if v_loo and cd_loo and len(v_loo) == len(cd_loo):
                comb = jackknife_se([a - b for a, b in zip(v_loo, cd_loo)])
            else:
                comb = math.hypot(num(e), cd["error"])
            return {"difference": v - cd["value"], "error": comb,
                    "sigma": (v - cd["value"]) / comb if math.isfinite(comb) and comb > 0 else math.nan}

        j = max(range(len(pts)), key=lambda i: pts[i]["factor"], default=None)
        out.append({"key": m.key, "label": m.label, "unit": m.unit, "scale": m.scale,
                    "seeds": used, "points": pts, "fit": fit, "cd": cd,
                    "limit_minus_cd": (against(fit["value"], fit["error"], fit["value_loo"])
                                       if fit["status"] == "extrapolated" else None),
                    "stiffest": None if j is None else pts[j]["name"],
                    "stiffest_minus_cd": (None if j is None else
                                          against(y[j], err[j], [r[j] for r in loo] if loo else None))})
    return out


def analyse(the_plan: Plan, records_root, comparisons_root, cd_dir=None, paper_dir=None, *,
            null_flips: int = 0, workers: int = 1, notebooks_dir="notebooks", progress=None) -> dict:
    """The study's numbers (module docstring) from the settings' records
    (``records_root/<name>/``), Contact Dynamics' records of the same piles (``cd_dir``; None or
    without records of these seeds: no engines' comparison) and the DEM's at the paper's scale
    (``paper_dir``: the cost there). Returns {reference, runs, sigma_limit, null_flips, cd,
    paper, fit_seeds, settings, measures, claims}."""
    from tiltpile.figures import same_piles as sp
    from tiltpile.figures import style

    say = progress or (lambda line: None)
    records_root, comparisons_root = Path(records_root), Path(comparisons_root)
    entries, preset = the_plan.entries, the_plan.preset
    code = code_digest(notebooks_dir)
    kw = dict(code=code, notebooks_dir=notebooks_dir)
    ref_done, comps, ref_docs = compare_settings(entries, records_root, comparisons_root, preset,
                                                 null_flips=null_flips, workers=workers,
                                                 progress=progress, **kw)
    known: dict[tuple, dict] = {}       # (label, seeds) -> figure documents

    def know(label, seeds, docs):
        known[(label, tuple(int(s) for s in seeds))] = docs

    if ref_docs is not None:
        know(REFERENCE, ref_done, ref_docs)
    for name, c in comps.items():
        if c is not None:
            know(REFERENCE, c["seeds"], c["documents"][REFERENCE])
            know(name, c["seeds"], c["documents"][name])
    own: dict[str, list[int]] = {}
    for p in entries:
        name, rec = p.setting.name, records_root / p.setting.name
        done = recorded(rec, p.seeds)
        if health_stops(read_runs(rec), p.seeds) or not done:
            continue
        own[name] = done
        if (name, tuple(done)) not in known:
            know(name, done, documents(rec, done, comparisons_root / OWN / name, preset, label=name,
                                       progress=progress, **kw))
    # Contact Dynamics on the same piles
    every = sorted({s for p in entries for s in p.seeds})
    cd_seeds = recorded(cd_dir, every) if cd_dir is not None else []
    cd_comps: dict[str, dict | None] = {}
    for p in entries:
        name = p.setting.name
        common = sorted(set(own.get(name, [])) & set(cd_seeds))
        if len(common) < sp.MIN_SEEDS:
            cd_comps[name] = None
            continue
        say(f"{name} against Contact Dynamics on {len(common)} seeds")
        line = None if progress is None else (lambda text, n=name: say(f"{n} against cd: {text}"))
        c = compare(cd_dir, records_root / name, name, common, comparisons_root / CD / name, preset,
                    ref_label=CD, ref_preset=cd_preset(preset), workers=workers, progress=line, **kw)
        know(CD, common, c["documents"][CD])
        know(name, common, c["documents"][name])
        cd_comps[name] = c

    def measured(label, rec, seeds):
        docs = known.get((label, tuple(seeds)))
        return measures_on(rec, seeds, comparisons_root / MEASURES_DIR / f"{label}_{_tag(seeds)}",
                           cd_preset(preset) if label == CD else preset, label=label,
                           fig2=None if docs is None else docs[FIG2],
                           workers=workers, progress=progress, **kw)

    own_measures = {name: measured(name, records_root / name, seeds) for name, seeds in own.items()}
    fit_names = [p.setting.name for p in entries if p.setting.name in own]
    fit_seeds = sorted(set.intersection(*(set(own[n]) for n in fit_names))) if fit_names else []
    fit_measures = {n: (own_measures[n] if own[n] == fit_seeds else
                        measured(n, records_root / n, fit_seeds)) for n in fit_names} if fit_seeds else {}
    cd_fit = (measured(CD, Path(cd_dir), fit_seeds) if fit_seeds and set(fit_seeds) <= set(cd_seeds)
              else None)
    paper_cost = None
    if paper_dir is not None:
        from tiltpile.record import record_files

        ps = sorted(int(f.stem.split("_")[1]) for f in record_files(paper_dir))
        paper_cost = dict(cost(paper_dir, ps), records=str(paper_dir), seeds=ps) if ps else None
    ref_verdicts = None if ref_docs is None else verdicts(ref_docs)
    settings = []
    ref_cost = cost(records_root / REFERENCE, entries[0].seeds)
    for p in entries:
        s, rec = p.setting, records_root / p.setting.name
        head = {"name": s.name, "overrides": list(s.overrides), "axis": s.axis,
                "committed": s.name == REFERENCE, "config_hash": p.config.hash(),
                "dem": dem_numbers(p)}
        e = setting_entry(head, p, read_runs(rec), rec, p.seeds, ref_done, comps.get(s.name),
                          ref_verdicts)
        docs = known.get((s.name, tuple(own[s.name]))) if s.name in own else None
        e["seeds_own"] = own.get(s.name, [])
        e["measures"] = own_measures.get(s.name)
        e["own_verdicts"] = (None if docs is None else
                             {k: v["verdict"] for k, v in verdicts(docs).items()})
        e["engines"] = (None if cd_comps.get(s.name) is None
                        else engines_summary(cd_comps[s.name], s.name))
        e["paper_scale"] = paper_scale(paper_cost, ref_cost, e["cost"])
        settings.append(e)
    by_name = {s["name"]: s for s in settings}
    return style.jsonable({
        "reference": REFERENCE, "runs": the_plan.runs, "sigma_limit": sp.SIGMA_LIMIT,
        "min_points": MIN_POINTS, "null_flips": int(null_flips),
        "cd": {"records": None if cd_dir is None else str(cd_dir), "seeds": cd_seeds,
               "available": bool(cd_seeds)},
        "paper": paper_cost, "fit_seeds": fit_seeds, "settings": settings,
        "measures": measures_numbers(fit_names, fit_measures, cd_fit, by_name) if fit_seeds else [],
        "claims": claims_numbers(settings, bool(cd_seeds))})


# ----------------------------------------------------------------------------------------------
# the figure


def plot(numbers: dict):
    """One panel per ``MEASURES`` number against x = k_n(reference) / k_n on the fit seeds (error
    bars: the numbers' errors), the line to the rigid limit x = 0 and the limit with its error
    where the number extrapolates (else the reason in the panel's title), and Contact Dynamics'
    number on the same seeds (a dashed line, its error a band); the last panel: DEM steps per run
    of each setting."""
    from tiltpile.figures import style

    fig, axs = style.figure(2, 3, width=style.DOUBLE_COLUMN_IN, height=4.6,
                            gridspec_kw=dict(wspace=0.38, hspace=0.62, left=0.08, right=0.99,
                                             bottom=0.11, top=0.88))
    flat = list(axs.flat)
    dem_c, cd_c = style.CYCLE[1], style.CYCLE[2]
    for ax, m in zip(flat, numbers["measures"]):
        sc = m["scale"]
        pts = [p for p in m["points"] if p["value"] is not None]
        ax.errorbar([p["x"] for p in pts], [sc * p["value"] for p in pts],
                    yerr=[sc * (p["error"] or 0.0) for p in pts], ls="none", marker="o", ms=3.5,
                    color=dem_c, capsize=2, label="DEM")
        f = m["fit"]
        if f["status"] == "extrapolated":
            ax.plot([0.0, 1.0], [sc * f["value"], sc * (f["value"] + f["slope"])], color=dem_c,
                    lw=0.8, ls="-")
            ax.errorbar([0.0], [sc * f["value"]], yerr=[sc * f["error"]], marker="D", ms=3.5,
                        mfc="none", color=dem_c, capsize=2, label="rigid limit")
            title = f"{m['label']}\nrigid limit {sc * f['value']:.4g} +- {sc * f['error']:.2g}"
        else:
            title = f"{m['label']}\ndoes not extrapolate: {f['status']}"
        cd = m["cd"]
        if cd and cd["value"] is not None:
            ax.axhline(sc * cd["value"], color=cd_c, ls="--", lw=0.8, label="Contact Dynamics")
            if cd["error"] is not None:
                ax.axhspan(sc * (cd["value"] - cd["error"]), sc * (cd["value"] + cd["error"]),
                           color=cd_c, alpha=0.15, lw=0)
        ax.set_xlim(-0.05, 1.08)
        ax.set_xlabel("k_n(reference) / k_n")
        ax.set_ylabel(_SHORT.get(m["key"], m["label"]), fontsize=6)
        ax.set_title(title, fontsize=5.5)
    ax = flat[len(numbers["measures"])] if len(numbers["measures"]) < len(flat) else None
    if ax is not None:
        rows = [(s["dem"]["x"], s["cost"].get("steps_per_run")) for s in numbers["settings"]
                if s["cost"].get("steps_per_run") is not None]
        ax.plot([r[0] for r in rows], [r[1] / 1e6 for r in rows], ls="none", marker="s", ms=3.5,
                color=dem_c)
        ax.set_xlim(-0.05, 1.08)
        ax.set_ylim(bottom=0)
        ax.set_xlabel("k_n(reference) / k_n")
        ax.set_ylabel("DEM steps per run [M]", fontsize=5.5)
        ax.set_title("cost", fontsize=5.5)
        for a in flat[len(numbers["measures"]) + 1:]:
            a.set_visible(False)
    handles, labels = flat[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, fontsize=5.5, loc="upper right", ncol=len(handles))
    fit_seeds = numbers["fit_seeds"]
    fig.suptitle(f"The DEM against its stiffness: seeds {seeds_text(fit_seeds)} at every k_n",
                 fontsize=7, x=0.08, ha="left")
    return fig


def write(numbers: dict, meta: dict, figures_dir) -> dict[str, Path]:
    """``figures_dir/stiffness_study.{png,pdf,json}`` (:func:`tiltpile.figures.style.save`: the
    JSON is {figure, **meta, numbers}) and ``stiffness_study.md`` (:func:`render` of that JSON)."""
    from .settings import write_outputs

    return write_outputs(NAME, plot, render, numbers, meta, figures_dir)


# ----------------------------------------------------------------------------------------------
# the report section: every sentence here, every number from the JSON

WORDS = {
    "intro": ("The {preset} preset's piles ({grains} grains, its history and ramp) in the soft-sphere "
              "DEM at {k} stiffnesses: {list} (`tiltpile stiffness-study`). The time step shrinks "
              "with the contact time, so every collision spans as many steps. Each stiffer setting "
              "is compared with k_n on the same piles (pile against pile; every figure number in "
              "jackknife errors, a number *moves* beyond {sigma:g} of them; every claim judged on "
              "both), and each setting with Contact Dynamics' runs of the same piles."),
    "rule": ("Each number is followed against x = k_n(preset) / k_n (the overlap scale m g / k_n in "
             "units of the preset's) on the piles every stiffness has (seeds {seeds}), and "
             "extrapolated to the rigid limit x = 0 by a straight line only where at least "
             "{min_points} stiffnesses give it with an error, it does not rise and fall between them "
             "by more than {sigma:g} errors, and the line passes within {sigma:g} errors of every "
             "point; otherwise it "
             "*does not extrapolate*. A value's error is its standard error over the piles "
             "(Fig. 2b's populations: the jackknife's); as every stiffness has the same piles, the "
             "errors of the steps, the line's residuals, the limit and the limit minus Contact "
             "Dynamics' number are the jackknife's over the piles, each pile left out of all of "
             "them at once."),
    "preliminary": "**Preliminary**: {what}.",
    "settings_head": ("| setting | k_n [m g / d] | dt [sqrt(d/g)] | steps per collision | piles | "
                      "DEM steps per run | core-hours per run | numbers moved (vs k_n) | claims "
                      "flipped (vs k_n) | 50 piles at the paper's scale |"),
    "numbers_head": ("| number | {cols} | rigid limit | Contact Dynamics | stiffest - CD | "
                     "limit - CD |"),
    "engines_intro": ("Against Contact Dynamics, pile against pile (DEM minus CD, 95% interval over "
                      "the piles):"),
    "engines_head": "| setting | piles | {cols} | figure numbers moved | claims differing |",
    "claims_intro": ("Per claim: its verdict at each k_n (on that stiffness' piles); whether a stiffer "
                     "k_n flips it on the same piles; and the engines on the same piles, toward the "
                     "rigid limit."),
    "claims_head": "| claim | {cols} | across k_n | the engines |",
    "same": "same at every k_n", "flips": "**flips** at {list}",
    "undecided": "undecided ({reason})",
    "eng_same": "same verdict in both engines at every k_n",
    "eng_same_from": "different at the softer k_n, **the same from {f} k_n** on",
    "eng_different": "**different at every k_n** (the difference survives to the stiffest)",
    "eng_different_from": "the same at the softer k_n, **different from {f} k_n** on",
    "shared": ("Both engines disagree with the paper, at every k_n or from the stiffer ones on "
               "(\"not our engine's\" holds there in the rigid limit): {list}."),
    "no_shared": "No disagreement with the paper is yet shared by both engines toward the rigid limit.",
    "paper": ("Cost at the paper's scale: the DEM's committed runs there (`{records}`, {n} piles at the "
              "preset's k_n) took {steps} M DEM steps and {ch} core-hours per run; at each k_n that "
              "times its steps per run over k_n's (the table's last column, {runs} piles)."),
    "no_cd": "Contact Dynamics' runs of these piles are not at hand: the engines are not compared.",
    "failed": "Stopped by the health rules (a failed setting, not compared): {list}.",
    "pending": "Not yet computed: {list}.",
    "no_fit": "No number is followed against the stiffness yet (no piles common to the stiffnesses).",
}


def _label(s: dict) -> str:
    f = s["dem"]["factor"]
    return "k_n" if s["committed"] else f"{f:g} k_n"


def _value_text(v, e, m: dict) -> str:
    if v is None or not math.isfinite(num(v)):
        return "n/a"
    spec = next(x.spec for x in MEASURES if x.key == m["key"])
    sc = m["scale"]
    err = f" +- {fmt(sc * num(e), '.2g')}" if e is not None and math.isfinite(num(e)) else ""
    return f"{fmt(sc * num(v), spec)}{err}"


def _against_text(a: dict | None, m: dict) -> str:
    if not a:
        return "n/a"
    sc = m["scale"]
    sig = f" ({fmt(a['sigma'], '+.1f')} errors)" if a.get("sigma") is not None else ""
    return f"{fmt(sc * num(a['difference']), '+.3g')}{sig}"


def _claim_stiffness(c: dict) -> str:
    st = c["stiffness"]
    if st["outcome"] == "flips":
        return WORDS["flips"].format(list="; ".join(
            f"{f['factor']:g} k_n ({f['reference']} -> {f['setting']})" for f in st["flips"]))
    if st["outcome"] == "same":
        return WORDS["same"]
    return WORDS["undecided"].format(reason=st["reason"])


def _claim_engines(c: dict) -> str:
    e = c["engines"]
    if e["outcome"] == "undecided":
        return WORDS["undecided"].format(reason=e["reason"])
    return WORDS[f"eng_{e['outcome']}"].format(f=f"{e['from']:g}" if e["from"] is not None else "")


def render(doc: dict) -> str:
    """The Markdown of the report section "The second engine in its rigid limit" from the
    study's JSON (``stiffness_study.json``): how it was made and the extrapolation's rule; one row
    per stiffness (k_n, dt, steps per collision, piles, cost, numbers moved and claims flipped
    against k_n, the cost of 50 piles at the paper's scale); one row per number (its value at each
    k_n on the common piles, the rigid limit or why it does not extrapolate, Contact Dynamics'
    on the same piles, and the limit against it); the engines pile against pile at each k_n; one
    row per claim (its verdict at each k_n, across k_n, the engines toward the rigid limit); the
    claims whose disagreement both engines share there; failed and pending settings."""
    n, st = doc["numbers"], doc.get("study", {})
    w = WORDS
    settings = n["settings"]
    by_name = {s["name"]: s for s in settings}
    lines = ["", f"## {SECTION}", "",
             w["intro"].format(preset=st.get("preset", "?"), grains=st.get("n_grains", "?"),
                               k=len(settings), sigma=n["sigma_limit"], list=", ".join(
                                   f"{_label(s)} (dt {s['dem']['dt']:.3g}, {s['seeds_planned']} piles)"
                                   for s in settings))]
    short = [s for s in settings if s["status"] != "failed" and len(s["seeds_done"]) < s["seeds_planned"]]
    if short:
        lines += ["", w["preliminary"].format(what="; ".join(
            f"{_label(s)} on {len(s['seeds_done'])} of {s['seeds_planned']} piles" for s in short))]
    lines += ["", w["settings_head"], "|---|---|---|---|---|---|---|---|---|---|"]
    for s in settings:
        c, cmp_, ps = s["cost"], s["comparison"], s["paper_scale"]
        moved = ("-" if s["committed"] else "n/a" if cmp_ is None else
                 f"{cmp_['n_moved']} of {cmp_['n_with_error']}")
        flips = ("-" if s["committed"] else "n/a" if s["flipped"] is None else
                 (f"{len(s['flipped'])} ({', '.join(s['flipped'])})" if s["flipped"] else "0"))
        status = {"failed": " (health stop)", "pending": " (not yet computed)"}.get(s["status"], "")
        steps = c.get("steps_per_run")
        paper = ("n/a" if not ps else
                 f"{fmt(ps['steps_per_run'] / 1e6, '.3g')} M steps, {fmt(ps['core_hours_per_run'], '.2g')} "
                 f"core-h a run; {fmt(ps['core_hours'], '.3g')} core-h")
        lines.append(f"| {_label(s)}{status} | {s['dem']['kn']:.3g} | {s['dem']['dt']:.3g} | "
                     f"{s['dem']['contact_steps']:.0f} | {len(s['seeds_done'])} of {s['seeds_planned']} | "
                     f"{'n/a' if steps is None else fmt(steps / 1e6, '.3g') + ' M'} | "
                     f"{fmt(c.get('core_hours_per_run'), '.2g')} | {moved} | {flips} | {paper} |")
    if n.get("paper"):
        p = n["paper"]
        lines += ["", w["paper"].format(records=p["records"], n=len(p["seeds"]),
                                        steps=fmt(num(p["steps_per_run"]) / 1e6, ".3g"),
                                        ch=fmt(p["core_hours_per_run"], ".2g"), runs=PAPER_RUNS)]
    if n["measures"]:
        names = [p["name"] for p in n["measures"][0]["points"]]
        cols = " | ".join(_label(by_name[x]) for x in names)
        lines += ["", w["rule"].format(seeds=seeds_text(n["fit_seeds"]), min_points=n["min_points"],
                                       sigma=n["sigma_limit"]),
                  "", w["numbers_head"].format(cols=cols), "|---|" + "---|" * (len(names) + 4)]
        for m in n["measures"]:
            unit = f" [{m['unit']}]" if m["unit"] else ""
            vals = " | ".join(_value_text(p["value"], p["error"], m) for p in m["points"])
            f = m["fit"]
            limit = (_value_text(f["value"], f["error"], m) if f["status"] == "extrapolated"
                     else f"does not extrapolate ({f['reason']})")
            cd = "n/a" if not m["cd"] else _value_text(m["cd"]["value"], m["cd"]["error"], m)
            lines.append(f"| {m['label']}{unit} | {vals} | {limit} | {cd} | "
                         f"{_against_text(m['stiffest_minus_cd'], m)} | "
                         f"{_against_text(m['limit_minus_cd'], m)} |")
    else:
        lines += ["", w["no_fit"]]
    if not n["cd"]["available"]:
        lines += ["", w["no_cd"]]
    else:
        labels = {"z_quiet": "<z>", "n_m_quiet": "<n_m>", "theta_first_onset": "first onset [deg]"}
        lines += ["", w["engines_intro"], "",
                  w["engines_head"].format(cols=" | ".join(labels[k] for k in ENGINE_KEYS)),
                  "|---|---|" + "---|" * len(ENGINE_KEYS) + "---|---|"]
        for s in settings:
            e = s["engines"]
            if e is None:
                continue
            sh = " | ".join(shift_text(e["shifts"].get(k)) for k in ENGINE_KEYS)
            lines.append(f"| {_label(s)} | {seeds_text(e['seeds'])} | {sh} | "
                         f"{e['n_moved']} of {e['n_with_error']} | {len(e['different'])} |")
    live = [s for s in settings if s["status"] != "failed"]
    live.sort(key=lambda s: s["dem"]["factor"])
    lines += ["", w["claims_intro"], "",
              w["claims_head"].format(cols=" | ".join(_label(s) for s in live)),
              "|---|" + "---|" * len(live) + "---|---|"]
    for c in n["claims"]:
        per = {p["name"]: p for p in c["per_setting"]}
        vs = " | ".join((per.get(s["name"]) or {}).get("verdict") or "n/a" for s in live)
        lines.append(f"| {c['text']} | {vs} | {_claim_stiffness(c)} | {_claim_engines(c)} |")
    if n["cd"]["available"]:
        shared = [c["text"] for c in n["claims"] if c["shared_disagreement"]]
        lines += ["", w["shared"].format(list="; ".join(shared)) if shared else w["no_shared"]]
    failed = [s for s in settings if s["status"] == "failed"]
    if failed:
        lines += ["", w["failed"].format(list="; ".join(
            f"{_label(s)} (" + ", ".join(stops_text(s["health_stops"])) + ")" for s in failed))]
    pending = [_label(s) for s in settings if s["status"] == "pending"]
    if pending:
        lines += ["", w["pending"].format(list=", ".join(pending))]
    return "\n".join(lines).lstrip("\n") + "\n"
