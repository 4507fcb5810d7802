"""The observables' tables: what one run's frames give, per frame and per critical cluster.

Each column is declared once, with its meaning, in ``FRAME_DOCS`` and ``CLUSTER_DOCS`` (in the
tables' column order); ``FRAME_COLUMNS`` and ``CLUSTER_COLUMNS`` are their keys and the listing
below is written from them. Adding an observable is one declaration and the code that fills it.

Every analysis parameter, with its default, is declared once in ``DEFAULT_PARAMS``; the functions
take them as keywords (``**params``) and check them with one function.

:func:`table_code` is a digest of the code that computes the tables (this module and the modules
of this package it imports, directly or not, without docstrings and comments): the observables'
caches and the run records are tied to it, so that a change to the computation makes them stale
without a hand-kept version number.

Columns
-------
{columns}
"""

from __future__ import annotations

import ast
import functools
import hashlib
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from . import avalanche as _av
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
    "frame": "stored frame index k",
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
    "n_active": "active contacts (f_n > 0) with at least one mobile grain (walls and fixed "
                "grains included)",
    "n_mobilized": "fully mobilized active contacts, counted as n_active",
    "ke_trans": "translational kinetic energy per mobile grain (m g d)",
    "ke_rot": "rotational kinetic energy per mobile grain (m g d)",
    "n_lost": "contacts active at k and not at k + 1 (-1 at the last frame)",
    "lost_fraction": "n_lost / active contacts at k (NaN at the last frame)",
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


# ----------------------------------------------------------------------------------------------
# the digest of the computation


def _code_only(source: str) -> str:
    """The source's syntax tree without docstrings (comments are not in it): what it computes."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree, annotate_fields=False, include_attributes=False)


def _local_imports(tree: ast.AST) -> set[str]:
    """Modules of this package a module imports (``from . import x``, ``from .x import y``)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            out.update([node.module] if node.module else [a.name for a in node.names])
    return out


def code_digest(directory, module: str) -> str:
    """Digest (16 hex digits) of ``directory/module.py`` and of every module of ``directory`` it
    imports relatively (``from . import x``, ``from .x import y``), directly or not, each without
    docstrings and comments."""
    here = Path(directory)
    todo, code = [module], {}
    while todo:
        name = todo.pop()
        if name in code:
            continue
        source = (here / f"{name}.py").read_text(encoding="utf-8")
        code[name] = _code_only(source)
        todo.extend(sorted(_local_imports(ast.parse(source)) - set(code)))
    h = hashlib.sha256()
    for name in sorted(code):
        h.update(name.encode() + b"\0" + code[name].encode() + b"\0")
    return h.hexdigest()[:16]


@functools.lru_cache(maxsize=None)
def table_code() -> str:
    """Digest of the code computing the tables (:func:`code_digest` of this module): the caches
    and records of other code are stale. Documentation edits keep it."""
    return code_digest(Path(__file__).parent, Path(__file__).stem)



def _params(overrides: dict) -> dict:
    unknown = set(overrides) - set(DEFAULT_PARAMS)
    if unknown:
        raise TypeError(f"unknown analysis parameter(s) {sorted(unknown)}; "
                        f"allowed: {sorted(DEFAULT_PARAMS)}")
    p = dict(DEFAULT_PARAMS, **overrides)
    if p["link"] not in ("contacts", "mobilized"):
        raise ValueError(f"link must be 'contacts' or 'mobilized', got {p['link']!r}")
    if p["cluster_region"] not in ("mobile", "bulk"):
        raise ValueError(f"cluster_region must be 'mobile' or 'bulk', got {p['cluster_region']!r}")
    if not 0.0 < p["cutoff"] < 1.0:
        raise ValueError(f"cutoff must be in (0, 1), got {p['cutoff']}")
    if p["lost_gap"] is not None and not p["lost_gap"] >= 0.0:
        raise ValueError(f"lost_gap must be None or >= 0 (d), got {p['lost_gap']}")
    if p["slide_ke"] is not None and not p["slide_ke"] > 0.0:
        raise ValueError(f"slide_ke must be None or > 0 (m g d per grain), got {p['slide_ke']}")
    if not p["slide_sustain_deg"] >= 0.0:
        raise ValueError(f"slide_sustain_deg must be >= 0 (deg), got {p['slide_sustain_deg']}")
    return p


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


def frame_contacts(radius, fixed, box_length, position, pair, force, status, *, mu=0.5,
                   mu_wall=None, **params) -> dict:
    """The contacts of one frame as every observable sees them (also the pile pictures).

    Contacts without a mobile grain (fixed-fixed, fixed-wall) carry no information and are
    dropped; active = f_n > 0; mobilized by :func:`~tiltpile.analysis.contacts.mobilized_mask`
    (sliding flag, or the threshold ``eps`` with mu / mu_wall); bulk grains by
    :func:`~tiltpile.analysis.contacts.bulk_mask`; critical clusters over mobile (or bulk) grains.
    params: analysis parameters (``DEFAULT_PARAMS``; this function reads eps, link,
    cluster_region, ray_spacing and touch_tol). Returns dict pair, force, status (the kept
    contacts), active, mobilized (per kept contact), bulk (N,) bool, top (N,) bool (free-surface
    grains, :func:`~tiltpile.analysis.contacts.top_layer`) and labels (N,) cluster labels (-1: none).
    """
    p = _params(params)
    eps, link, cluster_region = p["eps"], p["link"], p["cluster_region"]
    fixed = np.asarray(fixed, dtype=bool)
    n = fixed.size
    mobile = ~fixed
    pair = np.asarray(pair).reshape(-1, 2)
    force = np.asarray(force, dtype=float).reshape(-1, 2)
    jj = np.maximum(pair[:, 1], 0)
    moving = mobile[pair[:, 0]] | ((pair[:, 1] >= 0) & mobile[jj])
    pair, force = pair[moving], force[moving]
    status = None if status is None else np.asarray(status)[moving]
    active = _ct.active_mask(force)
    mu_c = mu if mu_wall is None else np.where(pair[:, 1] < 0, mu_wall, mu)
    mobil = _ct.mobilized_mask(force, status, mu_c, eps)
    top = _ct.top_layer(position, radius, fixed, box_length, p["ray_spacing"])
    bulk = _ct.bulk_mask(position, radius, fixed, pair, box_length, p["ray_spacing"],
                         p["touch_tol"], top=top)
    include = bulk if cluster_region == "bulk" else mobile
    labels = _cl.critical_clusters(n, pair, active, mobil, include, link)
    return {"pair": pair, "force": force, "status": status, "active": active,
            "mobilized": mobil, "bulk": bulk, "top": top, "labels": labels}


def frame_observables(radius, fixed, box_length, position, velocity, omega, pair, force, status,
                      theta_deg, *, mu=0.5, mu_wall=None,
                      **params) -> tuple[dict, pd.DataFrame, dict]:
    """Observables of one frame (arrays in, scalars and a cluster table out).

    radius (N,), fixed (N,) bool, box_length L, position (N, 2), velocity (N, 2), omega (N,),
    pair (C, 2), force (C, 2) [f_n, f_t], status (C,), theta_deg; mu / mu_wall friction of grain
    and wall contacts (only used with the threshold criterion eps); params: analysis parameters
    (``DEFAULT_PARAMS``).

    Contacts without a mobile grain (fixed-fixed, fixed-wall) are dropped first.

    Returns (row, clusters, keep): row a dict of per-frame scalars (bulk z, n_m, dz_gen, ...),
    clusters the :func:`tiltpile.analysis.clusters.cluster_table` of the frame, and keep a dict
    of arrays needed to compare with the next frame (pair, active, labels, position).
    """
    fixed = np.asarray(fixed, dtype=bool)
    n = fixed.size
    mobile = ~fixed
    p = _params(params)
    fc = frame_contacts(radius, fixed, box_length, position, pair, force, status, mu=mu,
                        mu_wall=mu_wall, **p)
    pair, active, mobil, bulk, labels = (fc["pair"], fc["active"], fc["mobilized"], fc["bulk"],
                                         fc["labels"])
    bc = _ct.bulk_coordination(pair, active, mobil, bulk, fixed, p["min_contacts"])
    z_all, n_m_all, _ = _ct.coordination(bc["z_i"], bc["m_i"], mobile & ~bc["rattler"])
    z_full = _ct.contact_counts(n, pair, active)
    m_full = _ct.contact_counts(n, pair, mobil)
    ctab = _cl.cluster_table(labels, position, z_full, m_full, theta_deg)
    # grains failing the single-grain criterion z_i - m_i / 2 >= (d + 1) / 2 (paper, Fig. 6), and
    # the fastest grain: a cluster holding a grain that cannot be at rest (docs/figures.md, Fig. 6)
    inc = labels >= 0
    unstable = inc & (z_full - m_full / 2.0 < 1.5 - 1e-9)
    speed = np.hypot(*np.asarray(velocity, dtype=float).reshape(-1, 2).T)
    k = len(ctab)
    ctab["n_unstable"] = np.bincount(labels[unstable], minlength=k)[:k].astype(np.int64)
    vmax = np.zeros(k)
    if k:
        np.maximum.at(vmax, labels[inc], speed[inc])
    ctab["speed_max"] = vmax
    # the two columns without a small exact form are held to float32 precision (7 digits, far
    # below what they resolve): a record then stores them in 4 bytes, losslessly
    for c in FLOAT32_CLUSTER_COLUMNS:
        ctab[c] = ctab[c].to_numpy(np.float64).astype(np.float32).astype(np.float64)
    rest = bulk & ~bc["rattler"] & (labels < 0)
    z_rest, _, n_rest = _ct.coordination(bc["z_i"], bc["m_i"], rest)
    e_t, e_r = _ct.kinetic_energy(radius, velocity, omega)
    nmob = int(mobile.sum())
    rig = _rg.rigid_clusters(n, pair, active, mobil, fixed, min_contacts=p["min_contacts"])
    sizes = ctab["size"].to_numpy()
    row = {
        "n_mobile": nmob, "n_bulk": bc["n"], "n_rattlers": bc["n_rattlers"],
        "z": bc["z"], "n_m": bc["n_m"], "dz_gen": bc["dz_gen"],
        "z_all": z_all, "n_m_all": n_m_all, "dz_gen_all": float(_ct.dz_gen(z_all, n_m_all)),
        "z_rest": z_rest, "n_rest": n_rest,
        "n_active": int(active.sum()), "n_mobilized": int(mobil.sum()),
        "ke_trans": float(e_t[mobile].mean()) if nmob else np.nan,
        "ke_rot": float(e_r[mobile].mean()) if nmob else np.nan,
        "largest_cluster": int(sizes.max()) if sizes.size else 0,
        "n_clusters": int(sizes.size), "n_in_clusters": int(sizes.sum()),
        "cluster_fraction": float(sizes.sum() / nmob) if nmob else np.nan,
        "rigid_fraction": rig.largest_size / nmob if nmob else np.nan,
        "floppy_per_grain": rig.n_floppy / nmob if nmob else np.nan,
        "rigid_spanning": _rg.spans(rig, fc["top"]),
        "n_rigid_left_out": rig.n_left_out,
    }
    return row, ctab, {"pair": pair, "active": active, "labels": labels, "position": position}


def lost_between(prev: dict, cur: dict, n: int, radius=None, box_length=None,
                 lost_gap: float | None = None) -> np.ndarray:
    """Which contacts of frame k (``prev``: pair, active, and position if ``lost_gap``) are lost
    by frame k + 1 (``cur``: pair, active, position): not active any more, and with ``lost_gap``
    also opened by more than lost_gap (d) (:func:`failure_between`). Returns (C_k,) bool."""
    lost = _ct.lost_contacts(prev["pair"], prev["active"], cur["pair"], cur["active"], n)
    if lost_gap is not None:
        gap = _ct.contact_gaps(prev["pair"], cur["position"], radius, box_length)
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
    failing = _ct.failing_grains(n, prev["pair"], lost, fixed)
    n_act = int(prev["active"].sum())
    nf = int(failing.sum())
    nfc = int((failing & (prev["labels"] >= 0)).sum())
    return {"n_lost": int(lost.sum()), "lost_fraction": lost.sum() / n_act if n_act else np.nan,
            "n_failing": nf, "n_failing_in_cluster": nfc,
            "failing_in_cluster_fraction": nfc / nf if nf else np.nan}


def run_observables(run, run_id: int | None = None, **params) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per-frame and per-cluster observables of one run (columns: FRAME_DOCS, CLUSTER_DOCS).

    run: path of a run file, or an open reader with the :func:`tiltpile.store.open_run` API.
    params: overrides of DEFAULT_PARAMS.
    """
    p = _params(params)
    if isinstance(run, (str, os.PathLike)):
        with _open_run(run) as r:
            return run_observables(r, run_id=_run_id(r, run) if run_id is None else run_id, **params)
    rid = _run_id(run, None) if run_id is None else int(run_id)
    scene = run.config.get("scene", {}) if isinstance(run.config, dict) else {}
    mu = float(scene.get("mu", 0.5))
    mu_wall = float(scene.get("mu_wall", mu))
    radius = np.asarray(run.radius, dtype=float)
    fixed = np.asarray(run.fixed, dtype=bool)
    L = float(run.box_length)
    nfr = int(run.n_frames)
    theta = np.asarray(run.theta_deg, dtype=float)
    mobile = ~fixed
    positions = np.empty((nfr, int(mobile.sum()), 2))
    rows, tabs = [], []
    prev = None
    for k in range(nfr):
        pos = np.asarray(run.position(k), dtype=float)
        positions[k] = pos[mobile]
        pair, force, status = run.contacts(k)
        row, ctab, keep = frame_observables(
            radius, fixed, L, pos, run.velocity(k), run.omega(k), pair, force, status, theta[k],
            mu=mu, mu_wall=mu_wall, **p)
        if prev is not None:
            rows[-1].update(failure_between(prev, keep, fixed, radius, L, p["lost_gap"]))
        row.update(n_lost=-1, lost_fraction=np.nan, n_failing=-1, n_failing_in_cluster=-1,
                   failing_in_cluster_fraction=np.nan)
        rows.append(row)
        ctab.insert(0, "frame", k)
        tabs.append(ctab)
        prev = keep
    frames = pd.DataFrame(rows)
    frames.insert(0, "frame", np.arange(nfr, dtype=np.int64))
    frames.insert(0, "run", rid)
    frames["step"] = np.asarray(run.step, dtype=np.int64)
    frames["time"] = np.asarray(run.time, dtype=float)
    frames["theta_deg"] = theta
    frames["iterations"] = np.asarray(run.iterations)
    frames["residual"] = np.asarray(run.residual, dtype=float)
    seg = _av.segment_avalanches(frames["lost_fraction"].to_numpy(), p["cutoff"], p["merge_gap"],
                                 n_contacts=frames["n_active"].to_numpy())
    rel = _av.theta_relative_to_onset(theta, seg["avalanching"], seg["onsets"])
    onset = np.zeros(nfr, dtype=bool)
    onset[seg["onsets"]] = True
    frames["avalanching"] = seg["avalanching"]
    frames["onset"] = onset
    frames["period"] = seg["period"]
    frames["theta_m"] = rel["theta_m"]
    frames["theta_to_onset"] = rel["theta_to_onset"]
    mean_d, max_d = _av.displacement_since_period_start(positions, seg["period_start"])
    frames["mean_displacement"] = mean_d
    frames["max_displacement"] = max_d
    frames = frames[FRAME_COLUMNS]
    clusters = pd.concat(tabs, ignore_index=True) if tabs else pd.DataFrame(columns=CLUSTER_COLUMNS)
    fi = clusters["frame"].to_numpy(np.int64)
    clusters.insert(0, "run", rid)
    clusters["theta_deg"] = theta[fi]
    clusters["avalanching"] = seg["avalanching"][fi]
    clusters["theta_to_onset"] = rel["theta_to_onset"][fi]
    clusters = clusters[CLUSTER_COLUMNS].astype({"run": np.int64, "frame": np.int64,
                                                 "cluster": np.int64, "size": np.int64})
    return frames, clusters


