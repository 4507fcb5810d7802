"""The contact number z = 2 N_c / N by counting rule: which contacts count, over which grains.

The analysis counts z one way (:mod:`tiltpile.analysis.contacts`: contacts with f_n > 0, wall and
fixed-grain contacts in, rattlers out, bulk grains). A contact number quoted without its rule
(the paper's <z> ~ 3.5) can differ from ours by what is counted, not by the packing. This module
counts z of one frame under a grid of rules, so that the rules can be set side by side.

A *rule* is a family of contacts, a threshold, and a variant:

* family ``"force"`` -- the frame's listed contacts with f_n > t <f_n> (``t = 0``: f_n > 0, the
  analysis's active contacts), <f_n> the mean normal force of the frame's active contacts
  (f_n > 0, at least one mobile grain). Forces below ~tol <f_n> are not resolved by the solver
  (Radjai & Richefeu 2009), so t of 1e-5 to 1e-2 asks how much of z hangs on unresolved forces;
* family ``"gap"`` -- every pair of bodies (grain-grain, grain-fixed grain, grain-wall, grain-floor)
  whose surface gap is <= g, found from the frame's positions and radii alone
  (:func:`gap_contacts`), for g from 0 up to the solver's alert distance: what a contact-dynamics
  code's contact list holds, or a geometric count with tolerance g;
* the variant (:class:`Variant`): ``walls`` -- contacts with a side wall, the floor or a fixed
  grain counted (True) or dropped (False); ``rattlers`` -- rattlers kept (True) or removed with
  their contacts (False); ``bulk`` -- the grains counted are the bulk grains (top and bottom
  single layers excluded, :func:`tiltpile.analysis.contacts.bulk_mask`) or every mobile grain.

Counting (as :func:`tiltpile.analysis.contacts.bulk_coordination`): over the set S of grains,
``z = (1/N) sum_{i in S} z_i`` with z_i the grain's counted contacts; a contact between two grains
of S counts once in N_c, a contact of a grain of S with anything outside S one half. Rattlers:
mobile grains with fewer than ``min_contacts`` contacts of the rule's family and threshold, walls
and fixed grains included (the physical network: dropping wall contacts does not make a grain
resting on the floor a rattler); single pass, as in the analysis. Fixed grains are never counted.

With family "force", t = 0 and :data:`ANALYSIS_VARIANT` the count is the analysis's ``z`` column
(:mod:`tiltpile.analysis.observables`) frame by frame.

Conventions as in :mod:`tiltpile.analysis.contacts` (box frame, d = 1, walls as negative ids:
-1 floor, -2 left wall, -3 right wall). Pure functions: arrays in, numbers out, no I/O.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tiltpile.paper_values import Z_MEAN

from . import contacts as _ct

PAPER_Z = Z_MEAN.value  # the paper's "average number of contacts for the whole pile", <z> ~ 3.5

#: relative force thresholds t of family "force": f_n > t <f_n>
FORCE_THRESHOLDS = (0.0, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1)
#: surface-gap thresholds g (d) of family "gap": gap <= g; those above the alert distance are dropped
GAP_THRESHOLDS = (0.0, 1e-7, 1e-6, 1e-5, 1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2e-2, 5e-2, 0.1)


class Variant(NamedTuple):
    """Which contacts and grains a count includes (module docstring)."""

    walls: bool     # contacts with side walls, the floor and fixed grains counted
    rattlers: bool  # rattlers kept in S (True) or removed with their contacts (False)
    bulk: bool      # S = bulk grains (True) or every mobile grain (False)

    @property
    def key(self) -> str:
        return (f"walls={'in' if self.walls else 'out'} rattlers={'in' if self.rattlers else 'out'} "
                f"grains={'bulk' if self.bulk else 'all'}")


#: the analysis's own rule (contacts.bulk_coordination): walls in, rattlers out, bulk grains
ANALYSIS_VARIANT = Variant(walls=True, rattlers=False, bulk=True)
#: every combination, the analysis's first
VARIANTS = tuple(Variant(w, r, b) for b in (True, False) for w in (True, False) for r in (False, True))


class Rule(NamedTuple):
    """A family ("force" or "gap") and its threshold (t, relative; or g, in d)."""

    family: str
    threshold: float

    @property
    def key(self) -> str:
        op = "f_n>" if self.family == "force" else "gap<="
        unit = "<f_n>" if self.family == "force" and self.threshold > 0 else ""
        return f"{op}{self.threshold:g}{unit}"


def rule_key(rule: Rule, variant: Variant) -> str:
    """One readable name of a rule and variant, e.g.
    ``'gap<=0.001 walls=in rattlers=out grains=bulk'``."""
    return f"{rule.key} {variant.key}"


def gap_grid(alert: float, thresholds=GAP_THRESHOLDS) -> tuple[float, ...]:
    """The gap thresholds from 0 up to the alert distance (d): ``thresholds`` <= alert, and alert
    itself when it is not on the grid. ValueError for alert <= 0."""
    if not alert > 0.0:
        raise ValueError(f"gap_grid: the alert distance must be > 0 (d), got {alert}")
    g = sorted({float(x) for x in thresholds if 0.0 <= x <= alert})
    if not g or g[-1] < alert:
        g.append(float(alert))
    return tuple(g)


def rules(force_thresholds=FORCE_THRESHOLDS, gap_thresholds=GAP_THRESHOLDS) -> list[Rule]:
    """The rules of the grid: every force threshold, then every gap threshold, in order."""
    return ([Rule("force", float(t)) for t in force_thresholds]
            + [Rule("gap", float(g)) for g in gap_thresholds])


# ----------------------------------------------------------------------------------------------
# contacts of a frame


def mobile_contacts(pair: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """(C,) bool: contacts with at least one mobile grain (the others carry no information)."""
    pair = np.asarray(pair).reshape(-1, 2)
    fixed = np.asarray(fixed, dtype=bool)
    i, j = pair[:, 0], pair[:, 1]
    return ~fixed[i] | ((j >= 0) & ~fixed[np.maximum(j, 0)])


def boundary_contacts(pair: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """(C,) bool: contacts with a wall or the floor (j < 0) or with a fixed grain (either end)."""
    pair = np.asarray(pair).reshape(-1, 2)
    fixed = np.asarray(fixed, dtype=bool)
    i, j = pair[:, 0], pair[:, 1]
    return (j < 0) | fixed[i] | ((j >= 0) & fixed[np.maximum(j, 0)])


def force_mask(fn: np.ndarray, threshold: float) -> np.ndarray:
    """Contacts with f_n > threshold * <f_n>, <f_n> the mean of the f_n > 0 among ``fn``.

    fn (C,) normal forces; threshold >= 0 (0: f_n > 0, the analysis's active contacts).
    Returns (C,) bool (all False when no contact carries a force).
    """
    fn = np.asarray(fn, dtype=float).ravel()
    if not threshold >= 0.0:
        raise ValueError(f"force_mask: threshold must be >= 0, got {threshold}")
    act = fn > 0.0
    if threshold == 0.0 or not act.any():
        return act
    return fn > threshold * fn[act].mean()


#: every pair of bodies within a surface gap (moved to :mod:`tiltpile.analysis.contacts`, where the
#: analysis's contact rules use it; kept here under its old name)
gap_contacts = _ct.gap_contacts


# ----------------------------------------------------------------------------------------------
# counting


def z_by_variant(pair: np.ndarray, counted: np.ndarray, fixed: np.ndarray, bulk: np.ndarray,
                 variants=VARIANTS, min_contacts: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """z = 2 N_c / N of one contact network under each variant (module docstring).

    pair (C, 2) contacts (j < 0 walls); counted (C,) bool: the contacts the rule's family and
    threshold keep; fixed (N,) bool; bulk (N,) bool (used by variants with ``bulk``);
    min_contacts: rattler threshold (0: no rattlers). Returns z (V,) float (NaN when no grain is
    counted) and n (V,) int, the grains counted, one per variant.
    """
    fixed = np.asarray(fixed, dtype=bool)
    bulk = np.asarray(bulk, dtype=bool)
    pair = np.asarray(pair).reshape(-1, 2)
    counted = np.asarray(counted, dtype=bool)
    n = fixed.size
    mobile = ~fixed
    ratt = _ct._rattler_mask(_ct._contact_counts(n, pair, counted), fixed, min_contacts)
    wall = boundary_contacts(pair, fixed)
    no_ratt = _ct.drop_contacts_of(pair, counted, ratt)
    z = np.full(len(variants), np.nan)
    cnt = np.zeros(len(variants), dtype=np.int64)
    cache: dict = {}
    for k, v in enumerate(variants):
        ck = (v.walls, v.rattlers)
        if ck not in cache:
            m = counted if v.rattlers else no_ratt
            cache[ck] = _ct._contact_counts(n, pair, m if v.walls else m & ~wall)
        sel = (bulk & mobile) if v.bulk else mobile
        if not v.rattlers:
            sel = sel & ~ratt
        z[k], _, cnt[k] = _ct._coordination(cache[ck], cache[ck], sel)
    return z, cnt


def frame_z(position: np.ndarray, radius: np.ndarray, fixed: np.ndarray, box_length: float,
            pair: np.ndarray, force: np.ndarray, bulk: np.ndarray,
            force_thresholds=FORCE_THRESHOLDS, gap_thresholds=GAP_THRESHOLDS, variants=VARIANTS,
            min_contacts: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """z of one frame under every rule of the grid (:func:`rules`) and every variant.

    position (N, 2), radius (N,), fixed (N,) bool, box_length L: the frame's grains; pair (C, 2),
    force (C, 2) [f_n, f_t]: its listed contacts (family "force"); bulk (N,) bool: its bulk grains
    (:func:`tiltpile.analysis.contacts.bulk_mask` on the listed contacts, as the analysis finds
    them); force_thresholds t (relative to <f_n>), gap_thresholds g (d; the gap contacts are
    searched up to max g); variants; min_contacts the rattler threshold.

    Returns z (R, V) float and n (R, V) int (grains counted), R = len(force_thresholds) +
    len(gap_thresholds) rows in the order of :func:`rules`, V = len(variants) columns.
    """
    fixed = np.asarray(fixed, dtype=bool)
    pair = np.asarray(pair).reshape(-1, 2)
    fn = np.asarray(force, dtype=float).reshape(-1, 2)[:, 0]
    keep = mobile_contacts(pair, fixed)
    fpair, fn = pair[keep], fn[keep]
    zs, ns = [], []
    for t in force_thresholds:
        z, n = z_by_variant(fpair, force_mask(fn, float(t)), fixed, bulk, variants, min_contacts)
        zs.append(z)
        ns.append(n)
    if len(gap_thresholds):
        gpair, gap = gap_contacts(position, radius, fixed, box_length, float(max(gap_thresholds)))
        for g in gap_thresholds:
            z, n = z_by_variant(gpair, gap <= g, fixed, bulk, variants, min_contacts)
            zs.append(z)
            ns.append(n)
    v = len(variants)
    return (np.asarray(zs, dtype=float).reshape(-1, v), np.asarray(ns, dtype=np.int64).reshape(-1, v))


def first_reaching(thresholds, z, target: float = PAPER_Z) -> dict:
    """Where a curve z(threshold) first reaches ``target``, thresholds increasing.

    thresholds (K,), z (K,) (NaN skipped). Returns dict ``threshold`` (the first grid point with
    z >= target, None if none), ``interpolated`` (the crossing, linear in log threshold between
    that point and the one before it, linear when the one before is 0; equal to ``threshold``
    when the first point already reaches it; None if none).
    """
    t = np.asarray(thresholds, dtype=float).ravel()
    z = np.asarray(z, dtype=float).ravel()
    ok = np.isfinite(z)
    t, z = t[ok], z[ok]
    hit = np.flatnonzero(z >= target)
    if hit.size == 0:
        return {"threshold": None, "interpolated": None}
    k = int(hit[0])
    if k == 0:
        return {"threshold": float(t[0]), "interpolated": float(t[0])}
    t0, t1, z0, z1 = t[k - 1], t[k], z[k - 1], z[k]
    f = (target - z0) / (z1 - z0)
    if t0 > 0.0:
        ti = float(np.exp(np.log(t0) + f * (np.log(t1) - np.log(t0))))
    else:
        ti = float(t0 + f * (t1 - t0))
    return {"threshold": float(t1), "interpolated": ti}
