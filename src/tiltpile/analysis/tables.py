"""The observables' tables: what one run's frames give, per frame and per critical cluster.

Each column is declared once, with its meaning, in ``FRAME_DOCS`` and ``CLUSTER_DOCS`` (in the
tables' column order); ``FRAME_COLUMNS`` and ``CLUSTER_COLUMNS`` are their keys and the listing
below is written from them.

Every analysis parameter, with its default, is declared once in ``DEFAULT_PARAMS``; the functions
take them as keywords (``**params``) and check them with one function.

Producers
---------
Each column is computed by one registered *producer* (``@_produces``: a function giving one
column or a small group, :class:`Producer`), at one of three stages: once per frame (from the
frame's grains and contacts), once per pair of successive frames (lost contacts), once per run
(over whole columns: the avalanches, theta_m). A producer declares what it reads (the stage's
inputs, or what earlier producers give: columns, or intermediates such as the frame's
``contacts``) and may read nothing else; the engine (:func:`run_observables`,
:func:`frame_observables`) runs them in order and names none of them.

Each column's *code* (:func:`column_code`) says which computation gave its values: a digest of
its producer's *version* (``@_produces(..., version=N)``), of the engine's (:data:`ENGINE_VERSION`)
and of the codes of what it reads (``theta_m`` reads the segmentation, which reads
``lost_fraction``, ...), so that bumping one producer changes the code of every column computed
from it. The observables' caches and the run records hold each column's code: a column is stale
when its code changed, and only then. A refactor that changes no value (moving a producer,
renaming its helpers, editing a docstring) changes no code and strands no record; an edit that
changes a column's values must bump its producer's version, and the golden-values test
(tests/analysis/test_golden_columns.py: every column, on a small committed run, at several
analysis parameter sets) fails until it does, naming the columns whose values moved. Parameter
values are not in the codes: caches and records hold the parameters and compare them. Records
written before the versions hold digests of the code (and older ones one digest of the whole table
code), read through :mod:`tiltpile.analysis.legacy_codes`.

Adding an observable: its declaration in ``FRAME_DOCS`` or ``CLUSTER_DOCS``, its producer here
(the code it needs may live in contacts.py, clusters.py, ...), its golden values
(``python tests/analysis/golden.py --update``) and a test; then the figure that
reads it adds it to its ``READS`` (src/tiltpile/figures/figN.py) and a notebook or study uses it.
Nothing else changes: every other column keeps its code (its version), so the committed
records keep serving the figures that do not read the new column, and the observables caches compute it where the run
files exist (``make records`` then writes it into the records); a figure reading it from records
that predate it is refused in one line naming it. No test or document lists every column: the
registry itself is checked at import (every declared column given by exactly one producer, every
read given before it), and tests/codehelpers.py adds a column this way in the tests of the codes.

Columns
-------
{columns}
"""

from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from . import avalanche as _av
from . import checks as _ck
from . import clusters as _cl
from . import contacts as _ct
from . import rigidity as _rg

DEFAULT_PARAMS = {
    "cutoff": 0.02,          # avalanche cutoff on the lost fraction
    "eps": None,             # None: mobilized = sliding status; else |f_t| >= mu f_n (1 - eps)
    "link": "contacts",      # cluster links: "contacts" | "mobilized"
    "cluster_region": "mobile",  # grains that may form clusters: "mobile" | "bulk"
    "min_contacts": 2,       # rattler threshold
    "ray_spacing": 0.1,      # top-layer ray spacing (d)
    "touch_tol": 0.05,       # bottom-layer touching tolerance (d)
    "merge_gap": 0,          # avalanche merging of short quiet gaps (frames)
    "lost_gap": None,        # None: a contact is lost when its f_n drops to 0 (force definition);
                             # a gap g (d): only if it has also opened by more than g (geometric)
    "contact_rule": "force",  # which pairs are contacts (z, rattlers, clusters, rigidity):
                              # "force" (f_n > 0) | "touching" (every listed contact) | "gap:<g>"
                              # (every pair within a surface gap g, d; contacts.parse_contact_rule)
    "lost_rule": None,       # the rule whose list a lost contact leaves; None: contact_rule
    "frame_stride": 1,       # analyse every k-th stored frame (lost contacts from k to k + stride)
    # first large slide of a run (run_table; avalanche.first_slide), not part of the cached tables:
    "slide_ke": None,        # KE per grain (m g d) above which a frame flows; None: the ensemble's
                             # Fig. 2a threshold (stats.ke_threshold)
    "slide_sustain_deg": 0.5,  # least tilt span of consecutive flowing frames that is a slide
}
# parameters of the per-run table only: they do not enter the per-frame cache or its freshness
RUN_TABLE_PARAMS = ("slide_ke", "slide_sustain_deg")

# per frame, in the table's order: column -> meaning (bulk: contacts.bulk_mask; rattlers removed
# by contacts.rattler_mask; counting rule: contacts.py)
FRAME_DOCS = {
    "run": "run id (the seed)",
    "frame": "stored frame index k (every frame_stride-th one is analysed)",
    "step": "time step of the frame",
    "time": "simulated time (sqrt(d / g))",
    "theta_deg": "inclination (deg)",
    "iterations": "NLGS sweeps of the frame's step",
    "residual": "the step's final solver residual",
    "n_mobile": "mobile grains",
    "n_bulk": "bulk grains (rattlers removed)",
    "n_rattlers": "rattlers among the bulk grains",
    "z": "bulk coordination number",
    "n_m": "bulk mobilization number",
    "dz_gen": "z - (d + 1) - n_m (generalized isostaticity, d = 2) in the bulk",
    "z_all": "coordination of all mobile grains, rattlers removed",
    "n_m_all": "mobilization of all mobile grains, rattlers removed",
    "dz_gen_all": "dz_gen of all mobile grains, rattlers removed",
    "z_rest": "coordination of the bulk non-rattlers in no critical cluster",
    "n_rest": "bulk non-rattlers in no critical cluster",
    "n_active": "active contacts (contact_rule; default f_n > 0) with at least one mobile grain "
                "(walls and fixed grains included)",
    "n_mobilized": "fully mobilized active contacts, counted as n_active",
    "ke_trans": "translational kinetic energy per mobile grain (m g d)",
    "ke_rot": "rotational kinetic energy per mobile grain (m g d)",
    "n_lost": "contacts active at k and not at the next analysed frame, both by lost_rule "
              "(default: the contact rule; -1 at the last frame)",
    "lost_fraction": "n_lost / contacts active by lost_rule at k (NaN at the last frame)",
    "n_failing": "mobile grains at an end of a lost contact (-1 at the last frame)",
    "n_failing_in_cluster": "failing grains that were in a critical cluster at k (-1 at the last "
                            "frame)",
    "failing_in_cluster_fraction": "n_failing_in_cluster / n_failing (NaN without failing grains)",
    "largest_cluster": "grains of the largest critical cluster",
    "n_clusters": "critical clusters",
    "n_in_clusters": "grains in critical clusters",
    "cluster_fraction": "n_in_clusters / n_mobile",
    "rigid_fraction": "mobile grains of the largest rigid cluster / n_mobile (rigidity.py: (3,3) "
                      "pebble game, sliding contacts 1 bar, others 2, rattlers left out)",
    "floppy_per_grain": "floppy modes of the contact network (relative to the ground) / n_mobile",
    "rigid_spanning": "the largest rigid cluster holds the ground and a free-surface grain",
    "n_rigid_left_out": "mobile grains left out of the rigidity count (rattlers, no contact)",
    "avalanching": "the frame belongs to an avalanche (lost_fraction above the cutoff; "
                   "avalanche.py)",
    "onset": "the frame starts an avalanche",
    "period": "index of the quiet period or avalanche the frame is in",
    "theta_m": "inclination of the next onset (NaN after the last)",
    "theta_to_onset": "theta_deg - theta_m",
    "mean_displacement": "mean displacement of the mobile grains since the period's start (d)",
    "max_displacement": "largest displacement of a mobile grain since the period's start (d)",
}
# per critical cluster per frame (clusters.py), in the table's order
CLUSTER_DOCS = {
    "run": "run id (the seed)",
    "frame": "stored frame index k",
    "theta_deg": "inclination of the frame (deg)",
    "avalanching": "the frame belongs to an avalanche",
    "theta_to_onset": "theta_deg - theta_m of the frame",
    "cluster": "cluster label within the frame",
    "size": "grains of the cluster",
    "z": "coordination of the cluster's grains (every active contact counted)",
    "n_m": "mobilization of the cluster's grains",
    "dz": "z - n_m (paper, Fig. 5; 2D)",
    "orientation_deg": "angle between the long axis and gravity (deg, 0 = along gravity; "
                       "to float32 precision)",
    "phi_deg": "angle of the long axis to the box's x axis (deg)",
    "rg_long": "gyration radius along the long axis (d)",
    "rg_short": "gyration radius along the short axis (d)",
    "x_com": "centre of the cluster's grains, x (d)",
    "y_com": "centre of the cluster's grains, y (d)",
    "n_unstable": "grains failing the single-grain criterion z_i - m_i / 2 >= 3/2",
    "speed_max": "largest speed of a grain of the cluster (sqrt(g d); to float32 precision)",
}
# cluster columns held to float32 precision (frame_observables)
FLOAT32_CLUSTER_COLUMNS = ("orientation_deg", "speed_max")
FRAME_COLUMNS = list(FRAME_DOCS)
CLUSTER_COLUMNS = list(CLUSTER_DOCS)


def _listing(title: str, docs: dict) -> str:
    w = max(map(len, docs))
    return "\n".join([title, *(f"    {k.ljust(w)}  {v}" for k, v in docs.items())])


__doc__ = __doc__.format(columns=_listing("per frame (one row per stored frame)::", FRAME_DOCS)
                         + "\n\n" + _listing("per cluster (one row per critical cluster per "
                                             "frame)::", CLUSTER_DOCS))


def _params(overrides: dict) -> dict:
    """DEFAULT_PARAMS with ``overrides`` applied, checked (:func:`_check_params`)."""
    unknown = set(overrides) - set(DEFAULT_PARAMS)
    if unknown:
        raise TypeError(f"unknown analysis parameter(s) {sorted(unknown)}; "
                        f"allowed: {sorted(DEFAULT_PARAMS)}")
    p = dict(DEFAULT_PARAMS, **overrides)
    _check_params(p)
    return p


def _check_params(p: dict) -> None:
    """Raise (TypeError, ValueError, one line) for a parameter value out of its range. It only
    raises, never changes ``p``: what it admits is compared by the caches and records, not
    carried in the columns' codes."""
    if p["link"] not in ("contacts", "mobilized"):
        raise ValueError(f"link must be 'contacts' or 'mobilized', got {p['link']!r}")
    if p["cluster_region"] not in ("mobile", "bulk"):
        raise ValueError(f"cluster_region must be 'mobile' or 'bulk', got {p['cluster_region']!r}")
    if not 0.0 < p["cutoff"] < 1.0:
        raise ValueError(f"cutoff must be in (0, 1), got {p['cutoff']}")
    _ct.parse_contact_rule(p["contact_rule"])
    if p["lost_rule"] is not None:
        _ct.parse_contact_rule(p["lost_rule"])
    if isinstance(p["frame_stride"], bool) or not isinstance(p["frame_stride"], (int, np.integer)) \
            or p["frame_stride"] < 1:
        raise ValueError(f"frame_stride must be an integer >= 1, got {p['frame_stride']!r}")
    if p["lost_gap"] is not None and not p["lost_gap"] >= 0.0:
        raise ValueError(f"lost_gap must be None or >= 0 (d), got {p['lost_gap']}")
    if p["slide_ke"] is not None and not p["slide_ke"] > 0.0:
        raise ValueError(f"slide_ke must be None or > 0 (m g d per grain), got {p['slide_ke']}")
    if not p["slide_sustain_deg"] >= 0.0:
        raise ValueError(f"slide_sustain_deg must be >= 0 (deg), got {p['slide_sustain_deg']}")


def _open_run(path):
    """Open a run file with the store's reader (the only module that knows the HDF5 layout)."""
    from tiltpile.store import open_run
    return open_run(path)


def _run_id(run, path) -> int:
    seed = getattr(run, "seed", None)
    if seed is not None:
        return int(seed)
    m = re.search(r"(\d+)", Path(path).stem) if path is not None else None
    if m is None:
        raise ValueError("cannot tell the run id: the run has no seed and its file name no number")
    return int(m.group(1))


_NOT_GIVEN = object()


def _grain_checks(fn: str, radius, fixed, box_length, mu, mu_wall) -> int:
    """A frame's grains checked (:mod:`tiltpile.analysis.checks`): radius (N,) > 0, fixed (N,)
    bool, box_length > 0, mu >= 0, mu_wall >= 0 or None. Returns N."""
    n = _ck.radii(fn, radius).shape[0]
    _ck.boolean(fn, "fixed", fixed, n, f"radius (N={n})")
    _ck.real(fn, "box_length", box_length, lo=0, lo_open=True)
    _ck.real(fn, "mu", mu, lo=0)
    _ck.real(fn, "mu_wall", mu_wall, lo=0, none_ok=True)
    return n


def _frame_checks(fn: str, n: int, position, pair, force, status, velocity=_NOT_GIVEN,
                  omega=_NOT_GIVEN) -> None:
    """A frame's arrays checked against its N grains: position (N, 2) finite, pair (C, 2) of
    grain indices and walls, force (C, 2) finite, status (C,) 0/1/2 or None; and, when given,
    velocity (N, 2), omega (N,) (NaN allowed: a run without velocities)."""
    like = f"radius (N={n})"
    _ck.shaped(fn, "position", position, (n, 2), like, finite=True)
    c = _ck.contact_pairs(fn, "pair", pair, n, like)
    _ck.shaped(fn, "force", force, (c, 2), f"pair (C={c})", finite=True, empty_ok=True)
    if status is not None:
        _ck.statuses(fn, "status", status, c, f"pair (C={c})")
    if velocity is not _NOT_GIVEN:
        _ck.shaped(fn, "velocity", velocity, (n, 2), like)
    if omega is not _NOT_GIVEN:
        _ck.shaped(fn, "omega", omega, (n,), like)


def frame_contacts(radius, fixed, box_length, position, pair, force, status, *, mu=0.5,
                   mu_wall=None, **params) -> dict:
    """The contacts of one frame as every observable sees them (also the pile pictures).

    Contacts without a mobile grain (fixed-fixed, fixed-wall) carry no information and are
    dropped; active: the contacts the rule ``contact_rule`` counts
    (:func:`~tiltpile.analysis.contacts.parse_contact_rule`; "force": f_n > 0; a "gap:<g>" rule
    adds every pair of bodies within the gap g that the run file does not list, with no force),
    and lost_active those of ``lost_rule`` (None: the contact rule), what a lost contact leaves;
    the bulk grains are found from the listed contacts under every rule; mobilized by :func:`~tiltpile.analysis.contacts.mobilized_mask`
    (sliding flag, or the threshold ``eps`` with mu / mu_wall); bulk grains by
    :func:`~tiltpile.analysis.contacts.bulk_mask`; critical clusters over mobile (or bulk) grains.
    params: analysis parameters (``DEFAULT_PARAMS``; this function reads eps, link,
    cluster_region, ray_spacing, touch_tol, contact_rule and lost_rule). Returns dict pair, force,
    status (the kept contacts, near pairs of a gap rule appended), active, lost_active, mobilized
    (per kept contact), bulk (N,) bool, top (N,) bool (free-surface
    grains, :func:`~tiltpile.analysis.contacts.top_layer`) and labels (N,) cluster labels (-1: none).
    """
    p = _params(params)
    n = _grain_checks("frame_contacts", radius, fixed, box_length, mu, mu_wall)
    _frame_checks("frame_contacts", n, position, pair, force, status)
    return _frame_contacts(radius, fixed, box_length, position, pair, force, status, mu, mu_wall, p)


def _frame_contacts(radius, fixed, box_length, position, pair, force, status, mu, mu_wall,
                    p: dict) -> dict:
    """:func:`frame_contacts` without the checks, at the checked analysis parameters ``p`` (the
    engine's, which checks a run's grains once and each frame's arrays)."""
    eps, link, cluster_region = p["eps"], p["link"], p["cluster_region"]
    rule = _ct.parse_contact_rule(p["contact_rule"])
    lost_rule = rule if p["lost_rule"] is None else _ct.parse_contact_rule(p["lost_rule"])
    fixed = np.asarray(fixed, dtype=bool)
    n = fixed.size
    mobile = ~fixed
    pair = np.asarray(pair).reshape(-1, 2)
    force = np.asarray(force, dtype=float).reshape(-1, 2)
    jj = np.maximum(pair[:, 1], 0)
    moving = mobile[pair[:, 0]] | ((pair[:, 1] >= 0) & mobile[jj])
    pair, force = pair[moving], force[moving]
    status = None if status is None else np.asarray(status)[moving]
    top = _ct._top_layer(position, radius, fixed, box_length, p["ray_spacing"])
    # the layers from the listed contacts, whatever the rule (the bulk is the same set of grains)
    bulk = _ct._bulk_mask(position, radius, fixed, pair, box_length, p["ray_spacing"],
                          p["touch_tol"], top=top)
    reach = [g for _, g in (rule, lost_rule) if g is not None]
    listed, gaps = np.ones(len(pair), dtype=bool), None
    if reach:
        pair, force, status, listed, gaps = _ct.with_near_pairs(
            pair, force, status, position, radius, fixed, box_length, max(reach))
    active = _ct.rule_mask(*rule, force, listed, gaps)
    lost_active = active if lost_rule == rule else _ct.rule_mask(*lost_rule, force, listed, gaps)
    mu_c = mu if mu_wall is None else np.where(pair[:, 1] < 0, mu_wall, mu)
    mobil = _ct._mobilized_mask(force, status, mu_c, eps)
    include = bulk if cluster_region == "bulk" else mobile
    labels = _cl._critical_clusters(n, pair, active, mobil, include, link)
    return {"pair": pair, "force": force, "status": status, "active": active,
            "lost_active": lost_active, "mobilized": mobil, "bulk": bulk, "top": top,
            "labels": labels}


def lost_between(prev: dict, cur: dict, n: int, radius=None, box_length=None,
                 lost_gap: float | None = None) -> np.ndarray:
    """Which contacts of frame k (``prev``: pair, active, and position if ``lost_gap``) are lost
    by frame k + 1 (``cur``: pair, active, position): not active any more, and with ``lost_gap``
    also opened by more than lost_gap (d) (:func:`failure_between`). Returns (C_k,) bool."""
    lost = _ct._lost_contacts(prev["pair"], prev["active"], cur["pair"], cur["active"], n)
    if lost_gap is not None:
        gap = _ct._contact_gaps(prev["pair"], cur["position"], radius, box_length)
        lost = lost & (gap > lost_gap)
    return lost


def failure_between(prev: dict, cur: dict, fixed: np.ndarray, radius=None, box_length=None,
                    lost_gap: float | None = None) -> dict:
    """Lost contacts and failing grains from frame k (``prev``) to k + 1 (``cur``).

    prev, cur: the ``keep`` dicts of :func:`frame_observables`. A contact active at k is lost
    when it is not active at k + 1 (force definition); with ``lost_gap`` (d; needs ``radius`` and
    ``box_length``) it must also have opened: its surface gap at k + 1 exceeds lost_gap (geometric
    definition; a rigid hyperstatic pile can shift its load off a contact that stays closed, which
    the force definition counts as a loss). Returns dict n_lost, lost_fraction (n_lost / active
    contacts at k), n_failing, n_failing_in_cluster (failing grains that were in a cluster at
    frame k), failing_in_cluster_fraction.
    """
    n = fixed.size
    lost = lost_between(prev, cur, n, radius, box_length, lost_gap)
    failing = _ct._failing_grains(n, prev["pair"], lost, fixed)
    n_act = int(prev["active"].sum())
    nf = int(failing.sum())
    nfc = int((failing & (prev["labels"] >= 0)).sum())
    return {"n_lost": int(lost.sum()), "lost_fraction": lost.sum() / n_act if n_act else np.nan,
            "n_failing": nf, "n_failing_in_cluster": nfc,
            "failing_in_cluster_fraction": nfc / nf if nf else np.nan}


# ----------------------------------------------------------------------------------------------
# the producers: one registered unit per column or small group of columns


@dataclass(frozen=True)
class Producer:
    """One registered unit of the tables' computation.

    stage: "frame" (once per stored frame: ``fn(q)``), "pair" (once per pair of successive
    frames k, k + 1: ``fn(prev, cur)``, the last frame taking ``fill``) or "run" (once per run,
    over whole columns: ``fn(q)``); gives: what ``fn`` returns, as a dict with exactly these
    keys: table columns ``"frames.<column>"`` / ``"clusters.<column>"`` (a scalar per frame,
    an array per cluster of the frame at the frame stage; arrays over the run at the run
    stage), or intermediates (names without a dot) that later producers read; reads: every
    name ``fn`` reads (an input of its stage, or what an earlier producer gives); ``q`` refuses
    any other. A frame-stage intermediate read at the run stage arrives as the list of its
    values over the frames.
    """

    stage: str
    fn: Callable
    gives: tuple
    reads: tuple
    fill: dict
    version: int = 1


_PRODUCERS: list[Producer] = []
# what the stages are given (run_observables, frame_observables)
FRAME_INPUTS = ("radius", "fixed", "box_length", "position", "velocity", "omega", "pair", "force",
                "status", "theta_deg", "mu", "mu_wall", "params")
RUN_INPUTS = ("run_id", "n_frames", "frame_index", "step", "time", "theta", "iterations",
              "residual", "cluster_frame", "params")


def _produces(stage: str, gives, reads=(), fill=None, version: int = 1):
    """Register the decorated function as a :class:`Producer`. ``version``: which computation
    of its values it is (the columns' codes, :func:`column_code`); bump it with any edit that
    changes a value it gives, never otherwise (module docstring)."""
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ValueError(f"version must be an integer >= 1, got {version!r}")

    def register(fn):
        _PRODUCERS.append(Producer(stage, fn, tuple(gives), tuple(reads), dict(fill or {}),
                                   version))
        return fn
    return register


class _View:
    """What a producer may read: the names it declared, nothing else."""

    def __init__(self, values: dict, producer: Producer):
        self._values, self._producer = values, producer

    def __getitem__(self, name):
        if name not in self._producer.reads:
            raise KeyError(f"{self._producer.fn.__name__} reads {name!r} without declaring it "
                           "(reads=...)")
        return self._values[name]


def _given(producer: Producer, out: dict) -> dict:
    """``out`` checked against what ``producer`` declares, its arrays as read-only views: a later
    producer cannot change what an earlier one gave (its version is not in their codes)."""
    if set(out) != set(producer.gives):
        raise RuntimeError(f"{producer.fn.__name__} gave {sorted(out)}, declared "
                           f"{sorted(producer.gives)}")
    return _read_only(out)


def _read_only(x):
    """``x`` with every array (inside dicts, lists, tuples) replaced by a read-only view."""
    if isinstance(x, np.ndarray):
        v = x.view()
        v.flags.writeable = False
        return v
    if isinstance(x, dict):
        return {k: _read_only(v) for k, v in x.items()}
    if isinstance(x, (tuple, list)) and type(x) in (tuple, list):
        return type(x)(_read_only(v) for v in x)
    return x


def _float32(a) -> np.ndarray:
    """Values held to float32 precision, as float64 (a record stores them in 4 bytes losslessly)."""
    return np.asarray(a, dtype=np.float64).astype(np.float32).astype(np.float64)


@_produces("frame", gives=("contacts",),
           reads=("radius", "fixed", "box_length", "position", "pair", "force", "status", "mu",
                  "mu_wall", "params"))
def _contacts(q):
    """The frame's contacts as every observable sees them (:func:`frame_contacts`)."""
    return {"contacts": _frame_contacts(q["radius"], q["fixed"], q["box_length"], q["position"],
                                        q["pair"], q["force"], q["status"], q["mu"], q["mu_wall"],
                                        q["params"])}


@_produces("frame", gives=("frames.n_mobile", "frames.n_active", "frames.n_mobilized"),
           reads=("fixed", "contacts"))
def _counts(q):
    fc = q["contacts"]
    return {"frames.n_mobile": int((~q["fixed"]).sum()), "frames.n_active": int(fc["active"].sum()),
            "frames.n_mobilized": int(fc["mobilized"].sum())}


@_produces("frame", gives=("bulk", "frames.n_bulk", "frames.n_rattlers", "frames.z", "frames.n_m",
                           "frames.dz_gen"),
           reads=("contacts", "fixed", "params"))
def _bulk(q):
    """Bulk z, n_m, dz_gen with rattlers removed (contacts.bulk_coordination)."""
    fc = q["contacts"]
    bc = _ct._bulk_coordination(fc["pair"], fc["active"], fc["mobilized"], fc["bulk"],
                                q["fixed"], q["params"]["min_contacts"])
    return {"bulk": bc, "frames.n_bulk": bc["n"], "frames.n_rattlers": bc["n_rattlers"],
            "frames.z": bc["z"], "frames.n_m": bc["n_m"], "frames.dz_gen": bc["dz_gen"]}


@_produces("frame", gives=("frames.z_all", "frames.n_m_all", "frames.dz_gen_all"),
           reads=("bulk", "fixed"))
def _all_grains(q):
    bc = q["bulk"]
    z_all, n_m_all, _ = _ct._coordination(bc["z_i"], bc["m_i"], ~q["fixed"] & ~bc["rattler"])
    return {"frames.z_all": z_all, "frames.n_m_all": n_m_all,
            "frames.dz_gen_all": float(_ct._dz_gen(z_all, n_m_all))}


@_produces("frame", gives=("frames.z_rest", "frames.n_rest"), reads=("contacts", "bulk"))
def _rest(q):
    fc, bc = q["contacts"], q["bulk"]
    rest = fc["bulk"] & ~bc["rattler"] & (fc["labels"] < 0)
    z_rest, _, n_rest = _ct._coordination(bc["z_i"], bc["m_i"], rest)
    return {"frames.z_rest": z_rest, "frames.n_rest": n_rest}


@_produces("frame", gives=("frames.ke_trans", "frames.ke_rot"),
           reads=("radius", "velocity", "omega", "fixed"))
def _energy(q):
    e_t, e_r = _ct._kinetic_energy(q["radius"], q["velocity"], q["omega"])
    mobile = ~q["fixed"]
    nmob = int(mobile.sum())
    return {"frames.ke_trans": float(e_t[mobile].mean()) if nmob else np.nan,
            "frames.ke_rot": float(e_r[mobile].mean()) if nmob else np.nan}


@_produces("frame", gives=("grain_contacts",), reads=("fixed", "contacts"))
def _grain_contacts(q):
    """Per grain: active (z) and mobilized (m) contacts with every partner, (N,) each."""
    fc, n = q["contacts"], q["fixed"].size
    return {"grain_contacts": {"z": _ct._contact_counts(n, fc["pair"], fc["active"]),
                               "m": _ct._contact_counts(n, fc["pair"], fc["mobilized"])}}


_CLUSTER_TABLE = ("cluster", "size", "z", "n_m", "dz", "orientation_deg", "phi_deg", "rg_long",
                  "rg_short", "x_com", "y_com")


@_produces("frame", gives=tuple(f"clusters.{c}" for c in _CLUSTER_TABLE),
           reads=("contacts", "position", "grain_contacts", "theta_deg"))
def _cluster_table(q):
    """clusters.cluster_table of the frame; the orientation held to float32 precision."""
    gc = q["grain_contacts"]
    tab = _cl._cluster_table(q["contacts"]["labels"], q["position"], gc["z"], gc["m"],
                            q["theta_deg"])
    out = {f"clusters.{c}": tab[c].to_numpy() for c in _CLUSTER_TABLE}
    out["clusters.orientation_deg"] = _float32(out["clusters.orientation_deg"])
    return out


@_produces("frame", gives=("clusters.n_unstable",),
           reads=("contacts", "grain_contacts", "clusters.cluster"))
def _unstable(q):
    """Grains failing the single-grain criterion z_i - m_i / 2 >= (d + 1) / 2 (paper, Fig. 6)."""
    labels, gc = q["contacts"]["labels"], q["grain_contacts"]
    k = len(q["clusters.cluster"])
    unstable = (labels >= 0) & (gc["z"] - gc["m"] / 2.0 < 1.5 - 1e-9)
    return {"clusters.n_unstable": np.bincount(labels[unstable], minlength=k)[:k].astype(np.int64)}


@_produces("frame", gives=("clusters.speed_max",),
           reads=("velocity", "contacts", "clusters.cluster"))
def _speed(q):
    """The fastest grain of each cluster: a cluster holding a grain that cannot be at rest
    (docs/figures.md, Fig. 6); held to float32 precision."""
    labels = q["contacts"]["labels"]
    k = len(q["clusters.cluster"])
    inc = labels >= 0
    speed = np.hypot(*np.asarray(q["velocity"], dtype=float).reshape(-1, 2).T)
    vmax = np.zeros(k)
    if k:
        np.maximum.at(vmax, labels[inc], speed[inc])
    return {"clusters.speed_max": _float32(vmax)}


@_produces("frame", gives=("frames.largest_cluster", "frames.n_clusters", "frames.n_in_clusters",
                           "frames.cluster_fraction"),
           reads=("clusters.size", "fixed"))
def _cluster_counts(q):
    sizes = q["clusters.size"]
    nmob = int((~q["fixed"]).sum())
    return {"frames.largest_cluster": int(sizes.max()) if sizes.size else 0,
            "frames.n_clusters": int(sizes.size), "frames.n_in_clusters": int(sizes.sum()),
            "frames.cluster_fraction": float(sizes.sum() / nmob) if nmob else np.nan}


@_produces("frame", gives=("frames.rigid_fraction", "frames.floppy_per_grain",
                           "frames.rigid_spanning", "frames.n_rigid_left_out"),
           reads=("fixed", "contacts", "params"))
def _rigidity(q):
    """Rigid clusters of the frame (rigidity.rigid_clusters; rattlers left out)."""
    fc, fixed = q["contacts"], q["fixed"]
    nmob = int((~fixed).sum())
    rig = _rg.rigid_clusters(fixed.size, fc["pair"], fc["active"], fc["mobilized"], fixed,
                             min_contacts=q["params"]["min_contacts"])
    return {"frames.rigid_fraction": rig.largest_size / nmob if nmob else np.nan,
            "frames.floppy_per_grain": rig.n_floppy / nmob if nmob else np.nan,
            "frames.rigid_spanning": _rg.spans(rig, fc["top"]),
            "frames.n_rigid_left_out": rig.n_left_out}


@_produces("frame", gives=("mobile_position",), reads=("position", "fixed"))
def _mobile_position(q):
    return {"mobile_position": q["position"][~q["fixed"]]}


def _keep(q) -> dict:
    """What frame k's contacts leave for comparison with frame k + 1 (failure_between)."""
    fc = q["contacts"]
    return {"pair": fc["pair"], "active": fc["lost_active"], "labels": fc["labels"],
            "position": q["position"]}


@_produces("pair", gives=("frames.n_lost", "frames.lost_fraction", "frames.n_failing",
                          "frames.n_failing_in_cluster", "frames.failing_in_cluster_fraction"),
           reads=("contacts", "position", "fixed", "radius", "box_length", "params"),
           fill={"frames.n_lost": -1, "frames.lost_fraction": np.nan, "frames.n_failing": -1,
                 "frames.n_failing_in_cluster": -1,
                 "frames.failing_in_cluster_fraction": np.nan})
def _failure(prev, cur):
    """Lost contacts and failing grains from frame k to k + 1 (:func:`failure_between`)."""
    f = failure_between(_keep(prev), _keep(cur), prev["fixed"], prev["radius"],
                        prev["box_length"], prev["params"]["lost_gap"])
    return {f"frames.{k}": v for k, v in f.items()}


@_produces("run", gives=("frames.run", "frames.frame", "frames.step", "frames.time",
                         "frames.theta_deg", "frames.iterations", "frames.residual"),
           reads=("run_id", "frame_index", "step", "time", "theta", "iterations", "residual"))
def _run_source(q):
    """What the run file says of each analysed frame (every ``frame_stride``-th stored one)."""
    return {"frames.run": q["run_id"], "frames.frame": np.asarray(q["frame_index"], dtype=np.int64),
            "frames.step": np.asarray(q["step"], dtype=np.int64),
            "frames.time": np.asarray(q["time"], dtype=float), "frames.theta_deg": q["theta"],
            "frames.iterations": np.asarray(q["iterations"]),
            "frames.residual": np.asarray(q["residual"], dtype=float)}


@_produces("run", gives=("segments", "frames.avalanching", "frames.onset", "frames.period"),
           reads=("frames.lost_fraction", "frames.n_active", "n_frames", "params"))
def _avalanches(q):
    """Quiet periods and avalanches by the lost-fraction cutoff (avalanche.segment_avalanches)."""
    p = q["params"]
    seg = _av.segment_avalanches(q["frames.lost_fraction"], p["cutoff"], p["merge_gap"],
                                 n_contacts=q["frames.n_active"])
    onset = np.zeros(q["n_frames"], dtype=bool)
    onset[seg["onsets"]] = True
    return {"segments": seg, "frames.avalanching": seg["avalanching"], "frames.onset": onset,
            "frames.period": seg["period"]}


@_produces("run", gives=("frames.theta_m", "frames.theta_to_onset"), reads=("theta", "segments"))
def _onset_angle(q):
    seg = q["segments"]
    rel = _av.theta_relative_to_onset(q["theta"], seg["avalanching"], seg["onsets"])
    return {"frames.theta_m": rel["theta_m"], "frames.theta_to_onset": rel["theta_to_onset"]}


@_produces("run", gives=("frames.mean_displacement", "frames.max_displacement"),
           reads=("mobile_position", "segments"))
def _displacement(q):
    mean_d, max_d = _av.displacement_since_period_start(np.stack(q["mobile_position"]),
                                                        q["segments"]["period_start"])
    return {"frames.mean_displacement": mean_d, "frames.max_displacement": max_d}


@_produces("run", gives=("clusters.run", "clusters.frame"),
           reads=("run_id", "cluster_frame", "frame_index"))
def _cluster_keys(q):
    """The run and the stored frame of each cluster (cluster_frame: its row of the frame table)."""
    return {"clusters.run": q["run_id"],
            "clusters.frame": np.asarray(q["frame_index"], dtype=np.int64)[q["cluster_frame"]]}


@_produces("run", gives=("clusters.theta_deg",), reads=("cluster_frame", "frames.theta_deg"))
def _cluster_theta(q):
    """The inclination of the cluster's frame."""
    return {"clusters.theta_deg": q["frames.theta_deg"][q["cluster_frame"]]}


@_produces("run", gives=("clusters.avalanching", "clusters.theta_to_onset"),
           reads=("cluster_frame", "frames.avalanching", "frames.theta_to_onset"))
def _cluster_onset_state(q):
    """The avalanche state and theta - theta_m of the cluster's frame."""
    fi = q["cluster_frame"]
    return {"clusters.avalanching": q["frames.avalanching"][fi],
            "clusters.theta_to_onset": q["frames.theta_to_onset"][fi]}


# ----------------------------------------------------------------------------------------------
# the engine: runs the producers in order (its version, ENGINE_VERSION, is in every column's code)

_CLUSTER_DTYPES = {"run": np.int64, "frame": np.int64, "cluster": np.int64, "size": np.int64}


def _frame_stage(inputs: dict) -> dict:
    """Every frame-stage producer on one frame's inputs (seen read-only): {name: value} of all
    they give."""
    q = _read_only(dict(inputs))
    for pr in _PRODUCERS:
        if pr.stage == "frame":
            q.update(_given(pr, pr.fn(_View(q, pr))))
    return q


def _frame_inputs(radius, fixed, box_length, position, velocity, omega, pair, force, status,
                  theta_deg, mu, mu_wall, params) -> dict:
    return {"radius": radius, "fixed": np.asarray(fixed, dtype=bool), "box_length": box_length,
            "position": position, "velocity": velocity, "omega": omega, "pair": pair,
            "force": force, "status": status, "theta_deg": theta_deg, "mu": mu,
            "mu_wall": mu_wall, "params": params}


def _split(q: dict, table: str) -> dict:
    head = table + "."
    return {k[len(head):]: v for k, v in q.items() if k.startswith(head)}


def frame_observables(radius, fixed, box_length, position, velocity, omega, pair, force, status,
                      theta_deg, *, mu=0.5, mu_wall=None,
                      **params) -> tuple[dict, pd.DataFrame, dict]:
    """Observables of one frame (arrays in, scalars and a cluster table out): the frame-stage
    producers.

    radius (N,), fixed (N,) bool, box_length L, position (N, 2), velocity (N, 2), omega (N,),
    pair (C, 2), force (C, 2) [f_n, f_t], status (C,), theta_deg; mu / mu_wall friction of grain
    and wall contacts (only used with the threshold criterion eps); params: analysis parameters
    (``DEFAULT_PARAMS``).

    Contacts without a mobile grain (fixed-fixed, fixed-wall) are dropped first.

    Returns (row, clusters, keep): row a dict of the frame's per-frame columns (bulk z, n_m,
    dz_gen, ...; not those of a pair of frames nor of the whole run), clusters its per-cluster
    columns (a DataFrame in table order, without those of the run stage), and keep a dict of
    arrays needed to compare with the next frame (pair, active, labels, position).
    """
    n = _grain_checks("frame_observables", radius, fixed, box_length, mu, mu_wall)
    _frame_checks("frame_observables", n, position, pair, force, status, velocity, omega)
    _ck.real("frame_observables", "theta_deg", theta_deg)
    q = _frame_stage(_frame_inputs(radius, fixed, box_length, position, velocity, omega, pair,
                                   force, status, theta_deg, mu, mu_wall, _params(params)))
    cl = _split(q, "clusters")
    return (_split(q, "frames"), pd.DataFrame({c: cl[c] for c in CLUSTER_COLUMNS if c in cl}),
            _keep(q))


# what run_observables reads of a run (tiltpile.store.Run's attributes)
_READER = ("config", "radius", "fixed", "box_length", "n_frames", "theta_deg", "step", "time",
           "iterations", "residual", "contacts", "position", "velocity", "omega")


def _check_reader(run) -> None:
    """A run reader has what :func:`run_observables` reads: every attribute of ``_READER`` and
    one value per frame in the per-frame ones."""
    fn = "run_observables"
    missing = [a for a in _READER if not hasattr(run, a)]
    if missing:
        _ck.fail(fn, "run", "be a run file's path or a reader with tiltpile.store.open_run's "
                 "attributes", f"{type(run).__name__} lacking {', '.join(missing)}", TypeError)
    nf = _ck.count(fn, "run.n_frames", run.n_frames)
    for name in ("theta_deg", "step", "time", "iterations", "residual"):
        _ck.shaped(fn, f"run.{name}", getattr(run, name), (nf,), f"run.n_frames ({nf})",
                   finite=name == "theta_deg")


def run_observables(run, run_id: int | None = None, **params) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per-frame and per-cluster observables of one run (columns: FRAME_DOCS, CLUSTER_DOCS).

    run: path of a run file, or an open reader with the :func:`tiltpile.store.open_run` API.
    params: overrides of DEFAULT_PARAMS. The run's grains are checked once, each frame's arrays
    as :func:`frame_observables` checks them; a refusal names the frame (a reader's).
    """
    p = _params(params)
    if run_id is not None:
        _ck.count("run_observables", "run_id", run_id)
    if isinstance(run, (str, os.PathLike)):
        with _open_run(run) as r:
            return run_observables(r, run_id=_run_id(r, run) if run_id is None else run_id, **params)
    _check_reader(run)
    rid = _run_id(run, None) if run_id is None else int(run_id)
    scene = run.config.get("scene", {}) if isinstance(run.config, dict) else {}
    mu = float(scene.get("mu", 0.5))
    mu_wall = float(scene.get("mu_wall", mu))
    n_grains = _grain_checks("run_observables", run.radius, run.fixed, run.box_length, mu, mu_wall)
    radius = np.asarray(run.radius, dtype=float)
    fixed = np.asarray(run.fixed, dtype=bool)
    L = float(run.box_length)
    # the analysed frames: every frame_stride-th stored one, from the first
    index = np.arange(0, int(run.n_frames), p["frame_stride"], dtype=np.int64)
    nfr = len(index)
    theta = np.asarray(run.theta_deg, dtype=float)[index]
    frame_p = [pr for pr in _PRODUCERS if pr.stage == "frame"]
    pair_p = [pr for pr in _PRODUCERS if pr.stage == "pair"]
    run_p = [pr for pr in _PRODUCERS if pr.stage == "run"]
    frame_gives = {g for pr in frame_p for g in pr.gives}
    collected = {n: [] for pr in run_p for n in pr.reads if n in frame_gives and "." not in n}
    rows, tabs, counts = [], [], []
    prev = None
    for pos, k in enumerate(index):
        k = int(k)
        pair, force, status = run.contacts(k)
        position = np.asarray(run.position(k), dtype=float)
        velocity, omega = run.velocity(k), run.omega(k)
        _frame_checks(f"run_observables: frame {k}", n_grains, position, pair, force, status,
                      velocity, omega)
        q = _frame_stage(_frame_inputs(radius, fixed, L, position, velocity, omega, pair, force,
                                       status, theta[pos], mu, mu_wall, p))
        row = _split(q, "frames")
        if prev is not None:
            for pr in pair_p:
                rows[-1].update(_split(_given(pr, pr.fn(_View(prev, pr), _View(q, pr))), "frames"))
        for pr in pair_p:
            row.update(_split(pr.fill, "frames"))
        rows.append(row)
        cl = _split(q, "clusters")
        tabs.append(pd.DataFrame({c: cl[c] for c in CLUSTER_COLUMNS if c in cl}))
        counts.append(len(tabs[-1]))
        for n in collected:
            collected[n].append(q[n])
        prev = q
    frames = pd.DataFrame(rows)
    clusters = pd.concat(tabs, ignore_index=True) if tabs else pd.DataFrame()
    rq = {"run_id": rid, "n_frames": nfr, "frame_index": index,
          "step": np.asarray(run.step)[index], "time": np.asarray(run.time)[index], "theta": theta,
          "iterations": np.asarray(run.iterations)[index],
          "residual": np.asarray(run.residual)[index],
          "cluster_frame": np.repeat(np.arange(nfr, dtype=np.int64), counts), "params": p}
    rq = _read_only(rq)
    rq.update(_read_only({f"frames.{c}": frames[c].to_numpy() for c in frames.columns}))
    rq.update(_read_only({f"clusters.{c}": clusters[c].to_numpy() for c in clusters.columns}))
    rq.update(collected)
    for pr in run_p:
        out = _given(pr, pr.fn(_View(rq, pr)))
        rq.update(out)
        for c, v in _split(out, "frames").items():
            frames[c] = v
        for c, v in _split(out, "clusters").items():
            clusters[c] = v
    frames = frames[FRAME_COLUMNS]
    clusters = clusters[CLUSTER_COLUMNS].astype(_CLUSTER_DTYPES)
    return frames, clusters


# ----------------------------------------------------------------------------------------------
# the registry's consistency and the columns' codes

#: the engine's version (run_observables, frame_observables and what they call to run the
#: producers, dtypes included): in every column's code; bump it with an engine edit that changes
#: any value
ENGINE_VERSION = 1


def _check_registry() -> dict:
    """Every column given by exactly one producer, every read given before it is read.
    Returns {name: producer} of every name given."""
    giver: dict = {}
    known = set(FRAME_INPUTS)
    for stage in ("frame", "pair", "run"):
        if stage == "run":
            known = set(RUN_INPUTS) | {g for g in giver}
        for pr in _PRODUCERS:
            if pr.stage != stage:
                continue
            if stage != "pair":
                missing = [r for r in pr.reads if r not in known]
            else:
                missing = [r for r in pr.reads if r not in known and r not in giver]
            if missing:
                raise RuntimeError(f"{pr.fn.__name__} reads {missing}, given by no earlier producer")
            for g in pr.gives:
                if g in giver:
                    raise RuntimeError(f"{g} is given by {giver[g].fn.__name__} and {pr.fn.__name__}")
                table, _, col = g.partition(".")
                if col and col not in {"frames": FRAME_DOCS, "clusters": CLUSTER_DOCS}.get(table, {}):
                    raise RuntimeError(f"{pr.fn.__name__} gives {g}, which FRAME_DOCS / "
                                       "CLUSTER_DOCS do not declare")
                giver[g] = pr
                if stage != "pair":
                    known.add(g)
            if stage == "pair" and set(pr.fill) != set(pr.gives):
                raise RuntimeError(f"{pr.fn.__name__}: fill must hold every column it gives")
    for table, docs in (("frames", FRAME_DOCS), ("clusters", CLUSTER_DOCS)):
        lost = [c for c in docs if f"{table}.{c}" not in giver]
        if lost:
            raise RuntimeError(f"{table} columns {lost} are declared but no producer gives them")
    return giver


_GIVER = _check_registry()


def _digest(parts) -> str:
    """16 hex digits of SHA-256 over the strings ``parts``."""
    import hashlib
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()[:16]


@functools.lru_cache(maxsize=None)
def producer_code(name: str) -> str:
    """The code (16 hex digits) of what gives ``name`` (a column ``"frames.z"`` or an
    intermediate): a digest of the engine's version, its producer's version and the codes of
    what it reads, names aside (renaming an intermediate or a helper keeps every code)."""
    pr = _GIVER[name]
    reads = sorted(producer_code(r) for r in pr.reads if r in _GIVER)
    return _digest([f"engine {ENGINE_VERSION}", f"producer {pr.version}", *reads])


@functools.lru_cache(maxsize=None)
def _column_code() -> tuple:
    return tuple((table, tuple((c, producer_code(f"{table}.{c}")) for c in docs))
                 for table, docs in (("frames", FRAME_DOCS), ("clusters", CLUSTER_DOCS)))


def column_code() -> dict:
    """{"frames": {column: code}, "clusters": {column: code}}: the code of every column of the
    tables (:func:`producer_code`). A cache or record holding a column of another code (followed
    through :func:`tiltpile.analysis.legacy_codes.superseded`) holds it as another computation
    gave it."""
    return {table: dict(cols) for table, cols in _column_code()}
