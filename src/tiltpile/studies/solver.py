"""The solver's choice (issue 72, items 2 and 3): which of the paper's claims depend on where NLGS
stops, and what each setting costs.

One ensemble of the study's preset (the default preset's 1000-grain piles and history) per
setting of the solver (``SETTINGS``: sweep order, cap, tolerance, time step), the same seeds as
the committed setting's (``reference``), each compared with it:

* **pile against pile and every figure number ensemble against ensemble**, by the same-piles
  machinery (:func:`tiltpile.figures.same_piles.study`: the per-seed numbers' paired differences
  with bootstrap intervals, every scalar of every figure shifted in units of its combined
  jackknife error, a number *moved* beyond ``SIGMA_LIMIT`` = 2 of them; with ``null_flips``, the
  count chance gives by exchanging each seed's two runs). Its ``<n_m>`` of the quiet frames, pile
  against pile, is the setting's **n_m shift**;
* **claim by claim**: the report's judges (:func:`tiltpile.report.document.judgements` with
  :data:`tiltpile.report.claims.CLAIMS`) on each side's figure documents of the common seeds; a
  claim is *flipped* by a setting whose verdict differs from the committed setting's on the same
  piles (neither "not measured");
* **its cost**: the sweeps and core-hours per run (the records' costs,
  :func:`tiltpile.analysis.ensemble_data.ensemble_cost`; a run is one single-threaded process, so
  its wall seconds are its core-seconds, on a machine as loaded as it was);
* **its health stops**: a run stopped by the health rules (``SimulationError``, recorded in the
  ensemble manifest as a failed run: ``health.energy_stop``, ``health.overlap_stop``,
  ``health.cap_hit_stop_fraction``, or a runaway: non-finite or grains out of the box) makes the
  setting *failed*: it is listed with its rule, not compared, and not a crash.

The settings are data (:class:`Setting`: name = the directory of its runs and records, the
override, the axis it varies); :func:`plan` validates them all through the configuration
module (:func:`tiltpile.studies.settings.configure`) before anything runs (an unknown key or
an out-of-range value is one ``ConfigError`` line). Outputs (:func:`write`): ``FIGURES/solver_study.{json,png,pdf}`` (the JSON: every
setting's numbers, every claim's dependence on the solver, and ``chart``, the points of the
figure), ``FIGURES/solver_study.md`` (:func:`render`, the report section "What the solver's
choice changes"). Each comparison is kept in ``FIGURES/same-piles/<setting>/`` (``same_piles.json``
and both sides' figure documents, as ``tiltpile same-piles`` writes them) with the digest of its
inputs (the records used, the figures' and analysis' code, the notebooks), and reused while that
digest holds: a study resumed over sessions computes only what changed. The machinery is
:mod:`tiltpile.studies.settings`, which the stiffness study shares.

The command is ``tiltpile solver-study`` (:mod:`tiltpile.cli.solver_study`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from tiltpile import config as cfgmod

# the machinery every study shares (studies.settings); also re-exported under this module's name,
# as the solver-study command and its tests use it (solver.runs_doc, solver.RUNS_FILE, ...)
from .settings import (COMPARISONS, INPUTS, NAME_RE, REFERENCE, RUNS_FILE, RUNS_FORMAT, Plan,  # noqa: F401
                       Planned, check_preset, check_runs, code_digest, compare, compare_settings,
                       configure, cost, failures, fingerprint, flipped, health_stops, read_runs,
                       recorded, runs_doc, setting_entry, stop_rule, verdicts, write_runs)
from .settings import documents as _documents
from .settings import fmt as _f
from .settings import num as _num
from .settings import seeds_text as _seeds_text
from .settings import shift as _shift  # noqa: F401
from .settings import shift_text as _shift_text
from .settings import stops_text as _stops_text

NAME = "solver_study"
SECTION = "What the solver's choice changes"


@dataclass(frozen=True)
class Setting:
    """One setting of the study: ``name`` (its directory below DATA and the records, and its
    label), ``override`` (``section.key=value``; None for the committed setting) and ``axis``
    (what it varies)."""
    name: str
    override: str | None
    axis: str

    @property
    def overrides(self) -> tuple[str, ...]:
        return () if self.override is None else (self.override,)

    @property
    def key(self) -> str | None:
        return None if self.override is None else self.override.split("=", 1)[0].strip()

    @property
    def value(self) -> str | None:
        return None if self.override is None else self.override.split("=", 1)[1].strip()


#: the axis each solver key varies
AXES = {"solver.sweep": "sweep order", "solver.max_iter": "cap (sweeps per step)",
        "solver.tol": "tolerance", "solver.dt": "time step"}
#: the marker of each axis in the chart (the committed setting: a star)
MARKERS = {"sweep order": "o", "cap (sweeps per step)": "s", "tolerance": "^", "time step": "D"}


def setting(override: str) -> Setting:
    """The setting of one override ``section.key=value``, named after it."""
    text = override.strip()
    key = text.split("=", 1)[0].strip()
    return Setting(text, text, AXES.get(key, key))


#: the study's settings, the committed one first, in the order their ensembles run (the order of
#: the session's driver: /work/runs/solver/<name>/); issue 72 item 2
SETTINGS: tuple[Setting, ...] = (Setting(REFERENCE, None, "committed"),) + tuple(setting(o) for o in (
    "solver.max_iter=300", "solver.tol=1e-4", "solver.tol=1e-5", "solver.dt=0.02",
    "solver.sweep=random", "solver.sweep=alternating", "solver.sweep=forward",
    "solver.max_iter=3000", "solver.dt=0.005", "solver.max_iter=10000", "solver.tol=1e-7"))

#: the figures whose claims rest on n_m, the mobilized contacts per grain, and how
N_M_FIGURES = {
    "fig1": "the marginal line z = 3 + n_m",
    "fig3": "critical clusters: grains with a fully mobilized contact",
    "fig4": "critical clusters and the marginal line",
    "fig5": "critical clusters: grains with a fully mobilized contact",
    "fig6": "delta z = z - n_m of the critical clusters",
    "fig7": "rigid clusters: a mobilized contact is one bar, not two",
}

_NAME_RE = NAME_RE


# ----------------------------------------------------------------------------------------------
# the plan, validated before anything runs (studies.settings: Plan, Planned, configure)


def _resolve(text: str) -> Setting:
    """A setting of ``SETTINGS`` by name, else the setting of an override ``solver.key=value``."""
    by_name = {s.name: s for s in SETTINGS}
    t = text.strip()
    if t in by_name:
        return by_name[t]
    if "=" not in t:
        raise cfgmod.ConfigError(f"--only {t!r}: neither a setting of the study ("
                                 f"{', '.join(by_name)}) nor an override solver.key=value")
    s = setting(t)
    if not s.key.startswith("solver.") or s.key.count(".") != 1:
        raise cfgmod.ConfigError(f"--only {t}: the solver study varies a solver.* key, not {s.key}")
    if not _NAME_RE.fullmatch(s.name):
        raise cfgmod.ConfigError(f"--only {t!r}: letters, digits and _ . = + - only (it names "
                                 "a directory; give the value without quotes)")
    return s


def plan(preset: str = "default", base=(), only=None, runs: int = 6) -> Plan:
    """The validated plan: every setting's configuration is the preset with ``base`` and the
    setting's override (``config.load``); ConfigError (one line naming the setting, the key or the
    value) for an unknown preset, key or setting, a value out of range, ``runs`` < 1, a setting
    named twice or one whose configuration is another's (the committed one's, say). ``only``:
    names of ``SETTINGS`` or overrides ``solver.key=value`` (None: every setting); the committed
    setting is always planned (the others are compared with it). Every setting runs the seeds
    0 .. runs - 1."""
    check_runs(runs)
    check_preset(preset)
    base = tuple(base)
    chosen = list(SETTINGS) if only is None else [SETTINGS[0]] + [_resolve(t) for t in only
                                                                  if t.strip() != REFERENCE]
    if only is not None and len(chosen) < 2:
        raise cfgmod.ConfigError("--only: name at least one setting besides the reference")
    return Plan(preset, base, runs, configure(preset, base, chosen, lambda s: range(runs)))


# ----------------------------------------------------------------------------------------------
# the runs, records, cost, comparisons and claims: studies.settings (stop_rule, runs_doc,
# read_runs, write_runs, health_stops, failures, recorded, cost, code_digest, fingerprint,
# compare, verdicts, flipped), imported above


def reference_documents(ref_dir, seeds, out_dir, preset: str, *, code: str,
                        notebooks_dir="notebooks", progress=None) -> dict[str, dict]:
    """{stem: figure document} of the committed setting on ``seeds`` (its verdicts), kept in
    ``out_dir`` with its inputs' digest like a comparison (:func:`studies.settings.documents`)."""
    return _documents(ref_dir, seeds, out_dir, preset, code=code, label=REFERENCE,
                      notebooks_dir=notebooks_dir, progress=progress)


def n_m_reason(figure: str) -> str | None:
    """How a claim of ``figure`` (its stem prefix, "fig4") rests on n_m; None if it does not."""
    return N_M_FIGURES.get(figure)


# ----------------------------------------------------------------------------------------------
# the study's numbers


def setting_numbers(p: Planned, runs: dict | None, rec_dir, seeds, ref_done, comparison: dict | None,
                    ref_verdicts: dict | None) -> dict:
    """One setting's entry of the study (module docstring; :func:`studies.settings.setting_entry`
    after the setting's name, override, axis and solver keys): status (done, partial, pending,
    failed), seeds done and compared, health stops and other failures, cost, the comparison's
    counts, the pile-against-pile shifts (``n_m_shift``: <n_m> of the quiet frames), the claims'
    verdicts beside the committed setting's on the same seeds and the claims flipped."""
    s = p.setting
    head = {"name": s.name, "override": s.override, "axis": s.axis, "key": s.key, "value": s.value,
            "committed": s.name == REFERENCE, "config_hash": p.config.hash(),
            "solver": {k: getattr(p.config.solver, k) for k in ("sweep", "max_iter", "tol", "dt")}}
    return setting_entry(head, p, runs, rec_dir, seeds, ref_done, comparison, ref_verdicts)


def claims_numbers(settings: list[dict], ref_verdicts: dict | None) -> list[dict]:
    """Per claim of the report: its text and figure, how it rests on n_m (None if it does not),
    the committed verdict (all the committed setting's piles), the settings compared, whether
    its verdict depends on the solver (True: a setting flips it; False: none of those compared
    does; None: none compared), the settings that flip it with their n_m shifts, and for an
    n_m-based claim the largest n_m shift it keeps its verdict through."""
    from tiltpile.report.claims import CLAIMS

    compared = [s for s in settings if not s["committed"] and s["verdicts"] is not None]
    out = []
    for c in CLAIMS:
        by = [s for s in compared if c.key in (s["flipped"] or [])]
        kept = [s for s in compared if c.key not in (s["flipped"] or [])
                and s["n_m_shift"] and math.isfinite(_num(s["n_m_shift"]["mean"]))]
        largest = max(kept, key=lambda s: abs(_num(s["n_m_shift"]["mean"])), default=None)
        reason = n_m_reason(c.figure)
        out.append({
            "key": c.key, "text": c.text, "figure": c.figure, "n_m_based": reason,
            "reference": (ref_verdicts or {}).get(c.key, {}).get("verdict"),
            "settings_compared": len(compared),
            "depends_on_solver": (True if by else False if compared else None),
            "flipped_by": [{"name": s["name"], "reference": s["verdicts"][c.key]["reference"],
                            "setting": s["verdicts"][c.key]["setting"], "n_m_shift": s["n_m_shift"]}
                           for s in by],
            "largest_kept_n_m_shift": (None if reason is None or largest is None else
                                       {"name": largest["name"], **largest["n_m_shift"]})})
    return out


def chart_points(settings: list[dict]) -> list[dict]:
    """The chart's points, one per setting: x the sweeps (and core-hours) per run (None without
    a finished run), y the figure numbers moved (of those with an error) and the claims flipped;
    the committed setting at 0 and 0; a failed or uncompared setting's y is None (the chart names
    it below the panels instead of placing it); ``seeds``: the piles compared."""
    pts = []
    for s in settings:
        c, cmp_ = s["cost"], s["comparison"]
        failed = s["status"] == "failed"
        pts.append({
            "name": s["name"], "axis": s["axis"], "committed": s["committed"], "status": s["status"],
            "seeds": len(s["seeds_compared"]),
            "sweeps_per_run": c.get("sweeps_per_run"), "core_hours_per_run": c.get("core_hours_per_run"),
            "numbers_moved": (0 if s["committed"] else None if failed or cmp_ is None
                              else cmp_["n_moved"]),
            "numbers_with_error": (None if cmp_ is None else cmp_["n_with_error"]),
            "chance_p95": (None if not cmp_ or not cmp_.get("null") else cmp_["null"]["p95"]),
            "claims_flipped": (None if failed or s["flipped"] is None else len(s["flipped"])),
            "n_m_shift": None if not s["n_m_shift"] else s["n_m_shift"]["mean"]})
    return pts


def decisions(settings: list[dict]) -> dict:
    """The two settings issue 72 carries to the paper's scale: the cheapest (sweeps per run)
    of the completely compared settings that move no figure number and flip no claim, and the
    one that moves <n_m> most; with the committed setting's sweeps per run."""
    ref = next((s for s in settings if s["committed"]), None)
    done = [s for s in settings if not s["committed"] and s["status"] == "done"
            and s["comparison"] is not None and len(s["seeds_compared"]) == s["seeds_planned"]]
    quiet = [s for s in done if s["comparison"]["n_moved"] == 0 and not s["flipped"]
             and s["cost"].get("sweeps_per_run") is not None]
    cheapest = min(quiet, key=lambda s: s["cost"]["sweeps_per_run"], default=None)
    shifted = [s for s in done if s["n_m_shift"] and math.isfinite(_num(s["n_m_shift"]["mean"]))]
    most = max(shifted, key=lambda s: abs(_num(s["n_m_shift"]["mean"])), default=None)
    return {"reference_sweeps_per_run": None if ref is None else ref["cost"].get("sweeps_per_run"),
            "cheapest_unmoved": None if cheapest is None else cheapest["name"],
            "cheapest_unmoved_sweeps_per_run": (None if cheapest is None
                                                else cheapest["cost"]["sweeps_per_run"]),
            "most_n_m": None if most is None else most["name"],
            "most_n_m_shift": None if most is None else most["n_m_shift"]}




def analyse(the_plan: Plan, records_root, comparisons_root, *, null_flips: int = 0, workers: int = 1,
            notebooks_dir="notebooks", progress=None) -> dict:
    """The study's numbers from the settings' records (``records_root/<name>/``: run_*.npz and
    runs.json), each setting with 2 or more seeds in common with the committed one (and no health
    stop) compared with it (:func:`studies.settings.compare_settings`, kept in
    ``comparisons_root/<name>/``). Returns {reference, runs, sigma_limit, null_flips, settings:
    [setting_numbers], claims: [claims_numbers], decisions, chart: [chart_points]}."""
    from tiltpile.figures import same_piles as sp
    from tiltpile.figures import style

    records_root = Path(records_root)
    seeds = the_plan.seeds
    ref_done, comps, ref_docs = compare_settings(
        the_plan.entries, records_root, comparisons_root, the_plan.preset,
        code=code_digest(notebooks_dir), null_flips=null_flips, workers=workers,
        notebooks_dir=notebooks_dir, progress=progress)
    ref_verdicts = None if ref_docs is None else verdicts(ref_docs)
    settings = []
    for p in the_plan.entries:
        rec = records_root / p.setting.name
        settings.append(setting_numbers(p, read_runs(rec), rec, seeds, ref_done,
                                        comps.get(p.setting.name), ref_verdicts))
    return style.jsonable({"reference": REFERENCE, "runs": the_plan.runs,
                           "sigma_limit": sp.SIGMA_LIMIT, "null_flips": int(null_flips),
                           "settings": settings, "claims": claims_numbers(settings, ref_verdicts),
                           "decisions": decisions(settings), "chart": chart_points(settings)})


# ----------------------------------------------------------------------------------------------
# the chart


def _short(name: str) -> str:
    return name.split("solver.", 1)[1] if name.startswith("solver.") else name


def plot(numbers: dict):
    """Two panels against the sweeps per run (linear, from 0, so that the costs' ratios show):
    the figure numbers moved beyond the limit (left; a grey bar: chance's 95th percentile where
    the null was computed) and the claims flipped (right); one point per setting (marker: its
    axis), the committed setting a star; failed and pending settings named below."""
    from matplotlib.ticker import MaxNLocator

    from tiltpile.figures import style

    fig, axs = style.figure(1, 2, width=style.DOUBLE_COLUMN_IN, height=3.0,
                            gridspec_kw=dict(wspace=0.25, left=0.07, right=0.99, bottom=0.3,
                                             top=0.91))
    placed = [p for p in numbers["chart"] if p["sweeps_per_run"] is not None
              and (p["committed"] or p["numbers_moved"] is not None)]
    colors = {a: style.CYCLE[i % len(style.CYCLE)] for i, a in enumerate(MARKERS)}
    for ax, key, label in ((axs[0], "numbers_moved",
                            f"figure numbers moved > {numbers['sigma_limit']:g} combined errors"),
                           (axs[1], "claims_flipped", "claims whose verdict flips")):
        top = 1
        for p in placed:
            y = p[key]
            if y is None:
                continue
            top = max(top, y, p["chance_p95"] or 0)
            m = "*" if p["committed"] else MARKERS.get(p["axis"], "x")
            c = "k" if p["committed"] else colors.get(p["axis"], style.COLORS["guide"])
            ax.plot([p["sweeps_per_run"]], [y], ls="none", marker=m, ms=9 if p["committed"] else 5,
                    mfc=c if p["committed"] else "none", mec=c, mew=1.0, zorder=3)
            if key == "numbers_moved" and p["chance_p95"] is not None:
                ax.plot([p["sweeps_per_run"]], [p["chance_p95"]], ls="none", marker="_", ms=10,
                        color=style.COLORS["guide"], zorder=2)
            tag = "committed" if p["committed"] else _short(p["name"])
            if p["seeds"] < numbers["runs"]:
                tag += f" ({p['seeds']} piles)"
            ax.annotate(tag, (p["sweeps_per_run"], y), xytext=(3, 3), textcoords="offset points",
                        fontsize=5.5)
        xmax = max((p["sweeps_per_run"] for p in placed), default=1.0) or 1.0
        ax.set_xlim(0, 1.2 * xmax)
        ax.set_ylim(-0.5, top * 1.15 + 0.5)
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
        ax.set_xlabel("NLGS sweeps per run")
        ax.set_ylabel(label)
    handles = [axs[0].plot([], [], ls="none", marker=m, mfc="none", mec=colors[a], label=a)[0]
               for a, m in MARKERS.items()]
    handles.append(axs[0].plot([], [], ls="none", marker="*", ms=9, color="k",
                               label="committed setting")[0])
    if any(p["chance_p95"] is not None for p in placed):
        handles.append(axs[0].plot([], [], ls="none", marker="_", ms=10, color=style.COLORS["guide"],
                                   label="chance, 95th percentile")[0])
    fig.legend(handles=handles, fontsize=5.5, loc="lower center", ncol=len(handles),
               bbox_to_anchor=(0.5, 0.09))
    notes = []
    failed = [s for s in numbers["settings"] if s["status"] == "failed"]
    if failed:
        notes.append("stopped by the health rules: " + "; ".join(
            f"{_short(s['name'])} ({', '.join(sorted({h['rule'] for h in s['health_stops']}))})"
            for s in failed))
    pending = [s["name"] for s in numbers["settings"] if s["status"] == "pending"]
    if pending:
        notes.append("not yet computed: " + ", ".join(_short(n) for n in pending))
    if notes:
        fig.text(0.07, 0.0, "\n".join(notes), fontsize=5.5, va="bottom")
    fig.suptitle(f"The solver's choice: {numbers['runs']} piles per setting, each against the "
                 "committed setting's same piles", fontsize=7)
    return fig


def write(numbers: dict, meta: dict, figures_dir) -> dict[str, Path]:
    """``figures_dir/solver_study.{png,pdf,json}`` (:func:`tiltpile.figures.style.save`: the JSON
    is {figure, **meta, numbers}) and ``solver_study.md`` (:func:`render` of that JSON)."""
    from .settings import write_outputs

    return write_outputs(NAME, plot, render, numbers, meta, figures_dir)


# ----------------------------------------------------------------------------------------------
# the report section: every sentence here, every number from the JSON

WORDS = {
    "intro": ("The {preset} preset's piles ({grains} grains, seeds {seeds}) under {k} settings of the "
              "NLGS solver besides the committed one ({committed}), one ensemble each "
              "(`tiltpile solver-study`). Each is compared with the committed setting on the same "
              "seeds: pile against pile, every figure number ensemble against ensemble (a number "
              "*moves* when it shifts by more than {sigma:g} combined jackknife errors), and every "
              "claim judged on both sides' figures. The claims' verdicts here are judged on the "
              "common piles, so a verdict that needs many runs may turn on one pile."),
    "preliminary": "**Preliminary**: {what}.",
    "settings_head": ("| setting | varies | piles | sweeps per run | core-hours per run | numbers "
                      "moved | by chance (95%) | claims flipped | <n_m> shift, quiet frames |"),
    "claims_intro": ("Per claim: whether its verdict depends on the solver (a setting flips it on "
                     "the same piles), which setting flips it and, for a claim resting on n_m, by "
                     "how much that setting moves <n_m> of the quiet frames (pile against pile, "
                     "95% interval over the seeds)."),
    "claims_head": "| claim | committed | depends on the solver? | flipped by | n_m |",
    "yes": "**yes**", "no": "no", "unknown": "not yet known",
    "not_n_m": "does not rest on n_m",
    "kept": "keeps its verdict through <n_m> {shift} ({name})",
    "cheapest": ("Cheapest setting that moves no figure number and flips no claim: {name}, {sweeps} "
                 "sweeps per run ({ratio} of the committed setting's {ref_sweeps})."),
    "no_cheapest": "No setting compared on every pile moves no figure number and flips no claim.",
    "most_n_m": "The setting that moves <n_m> most: {name}, {shift}.",
    "failed": "Stopped by the health rules (a failed setting, not compared): {list}.",
    "pending": "Not yet computed: {list}.",
    "none_compared": "No setting is compared yet.",
}


def render(doc: dict) -> str:
    """The Markdown of the report section "What the solver's choice changes" from the study's
    JSON (``solver_study.json``): how it was made, one row per setting (cost, numbers moved,
    claims flipped, n_m shift), one row per claim (does its verdict depend on the solver, which
    setting flips it, for n_m-based claims the size of the shift), the cheapest setting that
    keeps everything and the one that moves n_m most, the failed and pending settings."""
    n, st = doc["numbers"], doc.get("study", {})
    w = WORDS
    settings = n["settings"]
    ref = next(s for s in settings if s["committed"])
    others = [s for s in settings if not s["committed"]]
    sv = ref["solver"]
    committed = (f"sweep {sv['sweep']}, cap {sv['max_iter']} sweeps, tol {sv['tol']:g}, "
                 f"dt {sv['dt']:g}")
    lines = ["", f"## {SECTION}", "",
             w["intro"].format(preset=st.get("preset", "?"), grains=st.get("n_grains", "?"),
                               seeds=_seeds_text(range(n["runs"])), k=len(others),
                               committed=committed, sigma=n["sigma_limit"])]
    short = [s for s in settings if (s["committed"] and len(s["seeds_done"]) < s["seeds_planned"])
             or (s["comparison"] and len(s["seeds_compared"]) < s["seeds_planned"])]
    if short:
        lines += ["", w["preliminary"].format(what="; ".join(
            f"{'the committed setting' if s['committed'] else s['name']} on "
            f"{len(s['seeds_done'] if s['committed'] else s['seeds_compared'])} of "
            f"{s['seeds_planned']} piles" for s in short))]
    lines += ["", w["settings_head"], "|---|---|---|---|---|---|---|---|---|"]
    for s in settings:
        c, cmp_ = s["cost"], s["comparison"]
        moved = ("-" if s["committed"] else "n/a" if cmp_ is None else
                 f"{cmp_['n_moved']} of {cmp_['n_with_error']}")
        chance = "-" if not cmp_ or not cmp_.get("null") else _f(cmp_["null"]["p95"], "g")
        flips = ("-" if s["committed"] else "n/a" if s["flipped"] is None else
                 (f"{len(s['flipped'])} ({', '.join(s['flipped'])})" if s["flipped"] else "0"))
        status = {"failed": " (health stop)", "pending": " (not yet computed)"}.get(s["status"], "")
        lines.append(f"| {'committed' if s['committed'] else s['name']}{status} | {s['axis']} | "
                     f"{len(s['seeds_done'])} of {s['seeds_planned']} | "
                     f"{_f(c.get('sweeps_per_run'), '.3g')} | {_f(c.get('core_hours_per_run'), '.2g')} | "
                     f"{moved} | {chance} | {flips} | "
                     f"{'-' if s['committed'] else _shift_text(s['n_m_shift'])} |")
    lines += ["", w["claims_intro"], "", w["claims_head"], "|---|---|---|---|---|"]
    for c in n["claims"]:
        dep = {True: w["yes"], False: w["no"], None: w["unknown"]}[c["depends_on_solver"]]
        if c["depends_on_solver"] is False:
            k = c["settings_compared"]
            dep += f" ({k} setting{'' if k == 1 else 's'} compared)"
        by = "; ".join(f"{f['name']} ({f['reference']} -> {f['setting']})" for f in c["flipped_by"]) or "-"
        if c["n_m_based"] is None:
            nm = w["not_n_m"]
        elif c["flipped_by"]:
            nm = "; ".join(f"{f['name']}: {_shift_text(f['n_m_shift'])}" for f in c["flipped_by"])
        elif c["largest_kept_n_m_shift"]:
            k = c["largest_kept_n_m_shift"]
            nm = w["kept"].format(shift=_shift_text(k), name=k["name"])
        else:
            nm = "n/a"
        lines.append(f"| {c['text']} | {c['reference'] or 'n/a'} | {dep} | {by} | {nm} |")
    d = n["decisions"]
    lines.append("")
    if not any(s["comparison"] for s in others):
        lines.append(w["none_compared"])
    elif d["cheapest_unmoved"]:
        ratio = (_num(d["cheapest_unmoved_sweeps_per_run"]) / _num(d["reference_sweeps_per_run"])
                 if _num(d["reference_sweeps_per_run"]) else math.nan)
        lines.append(w["cheapest"].format(name=d["cheapest_unmoved"],
                                          sweeps=_f(d["cheapest_unmoved_sweeps_per_run"], ".3g"),
                                          ratio=_f(100 * ratio, ".0f") + "%",
                                          ref_sweeps=_f(d["reference_sweeps_per_run"], ".3g")))
    else:
        lines.append(w["no_cheapest"])
    if d["most_n_m"]:
        lines += ["", w["most_n_m"].format(name=d["most_n_m"], shift=_shift_text(d["most_n_m_shift"]))]
    failed = [s for s in settings if s["status"] == "failed"]
    if failed:
        lines += ["", w["failed"].format(list="; ".join(
            f"{s['name']} (" + ", ".join(_stops_text(s["health_stops"])) + ")" for s in failed))]
    pending = [s["name"] for s in settings if s["status"] == "pending"]
    if pending:
        lines += ["", w["pending"].format(list=", ".join(pending))]
    return "\n".join(lines).lstrip("\n") + "\n"
