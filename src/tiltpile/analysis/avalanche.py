"""Avalanche segmentation of a run from its lost-contact fraction (paper, Fig. 2b, c).

Frame convention: ``lost_fraction[k]`` is the fraction of the contacts active at frame k that are
no longer active at frame k + 1 (forward difference; NaN for the last frame). So frame k is the
last configuration before the contacts it lists are lost.

* Frame k is *avalanching* when ``lost_fraction[k] > cutoff`` (default 2%), else *quiet*. A NaN
  lost fraction (last frame, missing data) inherits the state of the previous frame (quiet at the
  start). Optionally, quiet gaps shorter than ``merge_gap`` frames between two avalanching
  stretches are merged into the avalanche (default 0: no merging).
* An avalanche *onset* is the first frame of each maximal stretch of avalanching frames; the
  failure angle of that avalanche is theta_m = theta[onset].
* Periods: maximal stretches of frames in the same state, numbered 0, 1, ... in time.
* theta - theta_m (column ``theta_to_onset``): for a quiet frame, relative to the *next* onset
  (<= 0; NaN when no onset follows); for an avalanching frame, relative to the onset of the
  avalanche it belongs to (>= 0).

Where the cutoff stops separating quiet from avalanching frames (``ResolutionWarning``; both
checks run in :func:`segment_avalanches`; ``tests/test_stability.py`` shows them on synthetic
and simulated series):

* Small piles (:func:`criterion_resolution`). Lost contacts are integers: with C active contacts
  a frame is avalanching when it loses more than cutoff * C of them. Below ``MIN_LOST_CONTACTS``
  = 3 (C < 150 at 2%) a single grain rolling off its neighbours -- it has z ~ 3-4 contacts and
  loses 1-3 -- already counts as an avalanche, and binomial noise of the quiet losses crosses the
  cutoff while small avalanches fall below it (at C = 50 the cutoff is one contact). Smoke piles
  (250 grains) have C ~ 410, i.e. 8 contacts; a 60-grain pile ~100, i.e. 2.
* Frames too far apart (:func:`frame_spacing_check`). Quiet frames lose contacts at a rate per
  degree, so their lost fraction grows with the spacing of frames; when the median lost fraction
  of the frames at or below the cutoff exceeds cutoff / 2, the quiet population reaches the
  cutoff and "avalanching" stands for "far apart". The median is taken over those frames, not
  over all: a paper-scale run flows for most of its frames (62% above 2% in the paper preset
  run of seed 0), and the median over all of them was 1.6 cutoffs at the recorded spacing (a
  warning on every such run), against 0.06 for its quiet frames. With no frame at or below the
  cutoff the median of all frames is used (above 1: flagged). Measured in cutoffs, median of the
  quiet frames / of all frames:

  | run (force definition) | as recorded | every 5th | every 10th | every 20th frame |
  |---|---|---|---|---|
  | smoke, seed 1 (0.1 deg) | 0 / 0 | 0.12 / 0.13 | 0.25 / 0.37 | 0.25 / 0.50 |
  | smoke, seed 2 | 0 / 0.24 | | 0.18 / 1.57 | 0.12 / 1.88 |
  | paper preset, seed 0 (0.05 deg) | 0.06 / 1.59 | 0.19 / 2.62 | 0.35 / 3.55 | |

  It is a heuristic for a drifting quiet population, not a guarantee: contacts lost and
  re-formed between two far-apart frames are not counted, so a short event can vanish. In the
  smoke run of seed 1 with every 20th frame (2 deg) the first frame above 2% moves from 6.9 to
  18 deg, and neither median flags it.

Onset measured two ways (:func:`first_slide`, :func:`run_onsets`)
------------------------------------------------------------------
The paper's theta_m is the first frame losing more than the cutoff of its contacts; in our piles
that fires first on *precursor* rearrangements (compaction and shear of the top ~12 d, kinetic
energy per grain 1e-5 to 5e-4 m g d). The avalanche angle of the literature (~21 deg for these
piles, Deboeuf et al. 2005) is the large surface *slide* (1e-3 to 1e-2 m g d per grain). A slide
is detected on the kinetic energy per grain E(theta): the first maximal stretch of consecutive
frames with E > threshold (the Fig. 2a threshold, where the energy density leaves the quiet power
law) that is *sustained*, i.e. whose frames span at least ``sustain_deg`` of tilt
(theta_last - theta_first >= sustain_deg). Precursors cross the threshold for a frame or a few;
a slide keeps the pile above it while the tilt goes on. The slide angle is theta of the stretch's
first frame. ``docs/figures.md`` (Fig. 2) gives the measured durations behind the default span.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

import warnings

from . import checks as _ck
from .contacts import displacement

MIN_LOST_CONTACTS = 3.0  # cutoff * contacts below this: the cutoff does not resolve avalanches
SPACING_LIMIT = 0.5      # quiet frames' median lost fraction above this x cutoff: too far apart


class ResolutionWarning(RuntimeWarning):
    """The lost-contact cutoff cannot separate quiet from avalanching frames in these data."""


def criterion_resolution(n_contacts, cutoff: float = 0.02, min_lost: float = MIN_LOST_CONTACTS,
                         warn: bool = True) -> float:
    """How many lost contacts the cutoff stands for: cutoff * median(n_contacts) (module docstring).

    n_contacts: active contacts per frame (array) or one number. Issues a ``ResolutionWarning``
    (if ``warn``) when the result is below ``min_lost``; NaN when no count is finite.
    cutoff in (0, 1).
    """
    fn = "criterion_resolution"
    _ck.asarray(fn, "n_contacts", n_contacts)
    _ck.real(fn, "cutoff", cutoff, lo=0, hi=1, lo_open=True, hi_open=True)
    _ck.real(fn, "min_lost", min_lost, lo=0)
    c = np.asarray(n_contacts, dtype=float).ravel()
    c = c[np.isfinite(c)]
    if c.size == 0:
        return float("nan")
    lost = float(cutoff * np.median(c))
    if warn and lost < min_lost:
        warnings.warn(f"avalanche cutoff {cutoff:g} of {np.median(c):.0f} active contacts is "
                      f"{lost:.2g} lost contacts < {min_lost:g}: one grain's rearrangement counts as "
                      "an avalanche and the quiet and avalanching frames are not separated (use a "
                      f"bigger pile, >= {min_lost / cutoff:.0f} contacts, or a larger cutoff)",
                      ResolutionWarning, stacklevel=2)
    return lost


def frame_spacing_check(lost_fraction, cutoff: float = 0.02, limit: float = SPACING_LIMIT,
                        warn: bool = True) -> float:
    """Median lost fraction of the quiet frames (at or below the cutoff; of all frames if none
    is), in units of the cutoff (module docstring).

    Issues a ``ResolutionWarning`` (if ``warn``) when it exceeds ``limit`` (1/2): the quiet frames
    then lose nearly the cutoff between two frames, i.e. frames are too far apart for the cutoff.
    NaN values are ignored (NaN when none is finite, or when the cutoff is not > 0).
    """
    _ck.asarray("frame_spacing_check", "lost_fraction", lost_fraction)
    _ck.real("frame_spacing_check", "cutoff", cutoff, nonfinite_ok=True)
    _ck.real("frame_spacing_check", "limit", limit, nonfinite_ok=True)
    lf = np.asarray(lost_fraction, dtype=float).ravel()
    lf = lf[np.isfinite(lf)]
    if lf.size == 0 or cutoff <= 0:
        return float("nan")
    quiet = lf[lf <= cutoff]
    typical = float(np.median(quiet if quiet.size else lf))
    ratio = typical / cutoff
    if warn and ratio > limit:
        which = (f"the {quiet.size} quiet frames (of {lf.size})" if quiet.size
                 else f"all {lf.size} frames (none at or below the cutoff)")
        warnings.warn(f"median lost fraction {typical:.3g} of {which} exceeds {limit:g} x the "
                      f"avalanche cutoff {cutoff:g}: quiet frames lose nearly the cutoff between "
                      "two frames, so frames are too far apart (record frames more often) or the "
                      "cutoff is too low", ResolutionWarning, stacklevel=2)
    return ratio


def _lost_fractions(fn: str, lost_fraction) -> np.ndarray:
    """Check a run's lost fractions: (F,) in [0, 1] or NaN (:mod:`tiltpile.analysis.checks`)."""
    lf = _ck.shaped(fn, "lost_fraction", lost_fraction, ("F",))
    if lf.size:
        with np.errstate(invalid="ignore"):
            out = (lf < 0) | (lf > 1)
        if out.any():
            k = int(np.flatnonzero(out)[0])
            _ck.fail(fn, "lost_fraction", "be in [0, 1] or NaN", f"{lf[k]} at frame {k}")
    return lf


def segment_avalanches(lost_fraction: np.ndarray, cutoff: float = 0.02,
                       merge_gap: int = 0, n_contacts=None) -> dict:
    """Split a run into quiet and avalanching periods (module docstring).

    lost_fraction (F,) in [0, 1] (NaN allowed); cutoff: threshold on the lost fraction;
    merge_gap: quiet stretches strictly shorter than this, between avalanches, are merged;
    n_contacts: active contacts per frame (or one number), optional: when given, the cutoff's
    resolution is checked (:func:`criterion_resolution`). The frame spacing is always checked
    (:func:`frame_spacing_check`). Both issue ``ResolutionWarning``; the segmentation is returned
    all the same.

    Returns dict of arrays: avalanching (F,) bool, onsets (K,) int64 frame indices,
    period (F,) int64 period id, period_start (F,) int64 first frame of each frame's period.
    """
    fn = "segment_avalanches"
    _lost_fractions(fn, lost_fraction)
    _ck.real(fn, "cutoff", cutoff, lo=0, hi=1, lo_open=True, hi_open=True)
    _ck.count(fn, "merge_gap", merge_gap, floats_ok=True)
    lf = np.asarray(lost_fraction, dtype=float)
    if n_contacts is not None:
        criterion_resolution(n_contacts, cutoff)
    frame_spacing_check(lf, cutoff)
    nf = lf.size
    av = np.zeros(nf, dtype=bool)
    prev = False
    for k in range(nf):                        # F ~ 1e3: a plain loop is fine and keeps NaN rule clear
        if np.isfinite(lf[k]):
            prev = lf[k] > cutoff
        av[k] = prev
    if merge_gap > 0 and nf:
        starts, ends = stretches(~av)
        for s, e in zip(starts, ends):
            if s > 0 and e < nf and (e - s) < merge_gap:
                av[s:e] = True
    change = np.ones(nf, dtype=bool)
    if nf:
        change[1:] = av[1:] != av[:-1]
    period = np.cumsum(change) - 1
    starts = np.flatnonzero(change)
    period_start = starts[period] if nf else np.zeros(0, dtype=np.int64)
    onsets = starts[av[starts]] if nf else np.zeros(0, dtype=np.int64)
    return {"avalanching": av, "onsets": onsets.astype(np.int64),
            "period": period.astype(np.int64), "period_start": np.asarray(period_start, dtype=np.int64)}


def stretches(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start (inclusive) and end (exclusive) indices of the maximal True stretches of a bool
    array, e.g. the avalanches of ``segment_avalanches(...)["avalanching"]``."""
    _ck.boolean("stretches", "mask", mask, None)
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    d = np.diff(m.astype(np.int8))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _frame_indices(fn: str, name: str, x, f: int, sorted_: bool = False) -> None:
    """Check frame indices: integers in [0, f), strictly increasing if ``sorted_``."""
    a = _ck.shaped(fn, name, x, ("K",), kinds="iu", empty_ok=True)
    if a.size and (a.min() < 0 or a.max() >= f):
        _ck.fail(fn, name, f"hold frame indices in [0, {f})", f"[{a.min()}, {a.max()}]")
    if sorted_ and a.size > 1 and not (np.diff(a) > 0).all():
        _ck.fail(fn, name, "be increasing frame indices", _ck.short(a.tolist()))


def theta_relative_to_onset(theta_deg: np.ndarray, avalanching: np.ndarray,
                            onsets: np.ndarray) -> dict:
    """theta_m and theta - theta_m of every frame (module docstring).

    theta_deg (F,), avalanching (F,) bool, onsets (K,) sorted frame indices.
    Returns dict: onset_index (F,) int64 frame index of the reference onset (-1 if none),
    theta_m (F,), theta_to_onset (F,) = theta - theta_m (NaN where no reference onset).
    """
    fn = "theta_relative_to_onset"
    f = _ck.shaped(fn, "theta_deg", theta_deg, ("F",), finite=True).size
    _ck.boolean(fn, "avalanching", avalanching, f, f"theta_deg (F={f})")
    _frame_indices(fn, "onsets", onsets, f, sorted_=True)
    theta = np.asarray(theta_deg, dtype=float)
    av = np.asarray(avalanching, dtype=bool)
    onsets = np.asarray(onsets, dtype=np.int64)
    k = np.arange(theta.size)
    ref = np.full(theta.size, -1, dtype=np.int64)
    if onsets.size:
        nxt = np.searchsorted(onsets, k, side="left")          # first onset >= k
        cur = np.searchsorted(onsets, k, side="right") - 1     # last onset <= k
        has_next = nxt < onsets.size
        ref[~av & has_next] = onsets[nxt[~av & has_next]]
        ref[av] = onsets[np.maximum(cur[av], 0)]
    theta_m = np.where(ref >= 0, theta[np.maximum(ref, 0)], np.nan)
    return {"onset_index": ref, "theta_m": theta_m, "theta_to_onset": theta - theta_m}


def onset_robustness(lost_fraction: np.ndarray, theta_deg: np.ndarray,
                     cutoffs=(0.01, 0.02, 0.03, 0.04), reference: float = 0.02,
                     max_shift: int = 10, merge_gap: int = 0) -> pd.DataFrame:
    """How much the avalanche onsets move when the cutoff changes (paper: 1-4%, 1-2 frames).

    Each onset found with the ``reference`` cutoff is matched to the nearest onset found with every
    cutoff in ``cutoffs``; a match further than ``max_shift`` frames counts as missing (NaN).

    Returns a DataFrame with one row per (reference onset, cutoff): onset (index of the reference
    onset in the run, 0..K-1), ref_frame, cutoff, frame, shift_frames (frame - ref_frame),
    shift_deg (theta[frame] - theta[ref_frame]).
    """
    fn = "onset_robustness"
    _ck.same_length(fn, lost_fraction=_ck.asarray(fn, "lost_fraction", lost_fraction),
                    theta_deg=_ck.asarray(fn, "theta_deg", theta_deg))
    for c in _ck.shaped(fn, "cutoffs", cutoffs, ("K",)).tolist():
        _ck.real(fn, "cutoffs", c, lo=0, hi=1, lo_open=True, hi_open=True)
    _ck.real(fn, "reference", reference, lo=0, hi=1, lo_open=True, hi_open=True)
    _ck.real(fn, "max_shift", max_shift, lo=0)
    theta = np.asarray(theta_deg, dtype=float)
    ref = segment_avalanches(lost_fraction, reference, merge_gap)["onsets"]
    rows = []
    for c in cutoffs:
        on = segment_avalanches(lost_fraction, c, merge_gap)["onsets"]
        for q, f0 in enumerate(ref):
            if on.size:
                f = on[np.argmin(np.abs(on - f0))]
                ok = abs(f - f0) <= max_shift
            else:
                ok = False
            rows.append({"onset": q, "ref_frame": int(f0), "cutoff": float(c),
                         "frame": float(f) if ok else np.nan,
                         "shift_frames": float(f - f0) if ok else np.nan,
                         "shift_deg": float(theta[f] - theta[f0]) if ok else np.nan})
    return pd.DataFrame(rows, columns=["onset", "ref_frame", "cutoff", "frame", "shift_frames",
                                       "shift_deg"])


def onset_robustness_ensemble(frames: pd.DataFrame, cutoffs=(0.01, 0.02, 0.03, 0.04),
                              reference: float = 0.02, max_shift: int = 10,
                              merge_gap: int = 0) -> pd.DataFrame:
    """:func:`onset_robustness` for every run of a per-frame table (columns run, frame,
    theta_deg, lost_fraction); the result gains a ``run`` column."""
    _ck.table("onset_robustness_ensemble", "frames", frames,
              ("run", "frame", "theta_deg", "lost_fraction"))
    parts = []
    for run, g in frames.sort_values(["run", "frame"]).groupby("run", sort=False):
        r = onset_robustness(g["lost_fraction"].to_numpy(), g["theta_deg"].to_numpy(), cutoffs,
                             reference, max_shift, merge_gap)
        r.insert(0, "run", run)
        parts.append(r)
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def displacement_since_period_start(positions: np.ndarray, period_start: np.ndarray,
                                    select: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mean and max grain displacement since the first frame of the current period.

    The paper checks that grains stay caged (< 1% of d) during the quiet period before an
    avalanche; with ``period_start`` from :func:`segment_avalanches`, a quiet frame is compared to
    the first frame of its quiet period (an avalanching frame to its avalanche's onset).

    positions (F, N, 2) in d; period_start (F,) int; select (N,) bool grains to include
    (default all). Returns (mean (F,), max (F,)) in d.
    """
    fn = "displacement_since_period_start"
    p = _ck.shaped(fn, "positions", positions, ("F", "N", 2), finite=True)
    _ck.shaped(fn, "period_start", period_start, (p.shape[0],), f"positions (F={p.shape[0]})",
               kinds="iu")
    _frame_indices(fn, "period_start", period_start, p.shape[0])
    if select is not None:
        _ck.boolean(fn, "select", select, p.shape[1], f"positions (N={p.shape[1]})")
    pos = np.asarray(positions, dtype=float)
    ps = np.asarray(period_start, dtype=np.int64)
    if select is not None:
        pos = pos[:, np.asarray(select, dtype=bool)]
    if pos.shape[1] == 0:
        nan = np.full(pos.shape[0], np.nan)
        return nan, nan.copy()
    disp = displacement(pos, pos[ps])           # (F, N)
    return disp.mean(axis=1), disp.max(axis=1)


def resegment(frames: pd.DataFrame, cutoff: float = 0.02, merge_gap: int = 0) -> pd.DataFrame:
    """Recompute avalanching / onset / theta_m / theta_to_onset of a per-frame table.

    frames: DataFrame with columns run, frame, theta_deg, lost_fraction (and n_active, if present,
    for the resolution check of :func:`segment_avalanches`) (as from
    :func:`tiltpile.analysis.load_observables`). Returns a copy with columns avalanching, onset
    (bool: frame is an onset), period, theta_m, theta_to_onset recomputed for ``cutoff``.
    (Displacement columns are not recomputed.)
    """
    _ck.table("resegment", "frames", frames, ("run", "frame", "theta_deg", "lost_fraction"))
    out = frames.sort_values(["run", "frame"]).copy()
    parts = []
    for _, g in out.groupby("run", sort=False):
        seg = segment_avalanches(g["lost_fraction"].to_numpy(), cutoff, merge_gap,
                                 n_contacts=g["n_active"].to_numpy() if "n_active" in g else None)
        rel = theta_relative_to_onset(g["theta_deg"].to_numpy(), seg["avalanching"], seg["onsets"])
        onset = np.zeros(len(g), dtype=bool)
        onset[seg["onsets"]] = True
        parts.append(pd.DataFrame({"avalanching": seg["avalanching"], "onset": onset,
                                   "period": seg["period"], "theta_m": rel["theta_m"],
                                   "theta_to_onset": rel["theta_to_onset"]}, index=g.index))
    new = pd.concat(parts) if parts else pd.DataFrame(
        columns=["avalanching", "onset", "period", "theta_m", "theta_to_onset"])
    for c in new.columns:
        out[c] = new[c]
    return out


def first_slide(theta_deg, ke_per_grain, threshold: float, sustain_deg: float) -> float:
    """Tilt angle of the first sustained large slide (module docstring, "Onset measured two ways").

    theta_deg (F,) increasing tilt of the frames (deg); ke_per_grain (F,) kinetic energy per
    grain (m g d); threshold: energy per grain above which a frame is flowing; sustain_deg: the
    least tilt span (theta of the stretch's last frame minus its first, deg) of consecutive
    flowing frames that counts as a slide (0: any single frame above the threshold).
    A non-finite energy breaks a stretch. Returns theta of the first frame of the first sustained
    stretch, NaN when there is none (also with a non-finite threshold). A stretch still running
    at the last frame counts only if it already spans ``sustain_deg``.
    """
    _ck.asarray("first_slide", "theta_deg", theta_deg)
    _ck.asarray("first_slide", "ke_per_grain", ke_per_grain)
    _ck.real("first_slide", "threshold", threshold, nonfinite_ok=True)
    _ck.real("first_slide", "sustain_deg", sustain_deg, nonfinite_ok=True)
    theta = np.asarray(theta_deg, dtype=float).ravel()
    ke = np.asarray(ke_per_grain, dtype=float).ravel()
    if theta.shape != ke.shape:
        raise ValueError(f"first_slide: theta_deg {theta.shape} and ke_per_grain {ke.shape} differ")
    if not sustain_deg >= 0:
        raise ValueError(f"first_slide: sustain_deg must be >= 0, got {sustain_deg}")
    if not np.isfinite(threshold):
        return float("nan")
    with np.errstate(invalid="ignore"):
        above = np.isfinite(ke) & (ke > threshold)
    for s, e in zip(*stretches(above)):
        if theta[e - 1] - theta[s] >= sustain_deg - 1e-9:
            return float(theta[s])
    return float("nan")


def run_onsets(frames: pd.DataFrame, ke_threshold: float, sustain_deg: float,
               ke_column: str = "ke_trans") -> pd.DataFrame:
    """Per run: the first onset by the lost-contact cutoff and the first sustained slide.

    frames: per-frame table (run, frame, theta_deg, onset, avalanching and ``ke_column``), as from
    :func:`tiltpile.analysis.load_observables`. ke_threshold, sustain_deg: :func:`first_slide`.
    Returns a DataFrame, one row per run (sorted): run, n_frames, theta_end (last frame's tilt),
    n_onsets, theta_first_onset (NaN: no onset), theta_first_slide (NaN: no sustained slide
    before theta_end), slide_minus_onset (deg), ke_max (largest energy per grain of the run).
    """
    fn = "run_onsets"
    if not isinstance(ke_column, str):
        _ck.fail(fn, "ke_column", "be a column name", _ck.short(ke_column), TypeError)
    _ck.table(fn, "frames", frames, ("run", "frame", "theta_deg", "onset", ke_column))
    _ck.real(fn, "ke_threshold", ke_threshold, nonfinite_ok=True)
    _ck.real(fn, "sustain_deg", sustain_deg, nonfinite_ok=True)
    if not sustain_deg >= 0:
        _ck.fail(fn, "sustain_deg", "be >= 0", repr(sustain_deg))
    rows = []
    for run, g in frames.sort_values(["run", "frame"], kind="stable").groupby("run", sort=True):
        th = g["theta_deg"].to_numpy(float)
        ke = g[ke_column].to_numpy(float)
        on = g["onset"].to_numpy(bool)
        t_on = float(th[on][0]) if on.any() else float("nan")
        t_sl = first_slide(th, ke, ke_threshold, sustain_deg)
        fin = ke[np.isfinite(ke)]
        rows.append({"run": int(run), "n_frames": int(th.size),
                     "theta_end": float(th[-1]) if th.size else float("nan"),
                     "n_onsets": int(on.sum()), "theta_first_onset": t_on,
                     "theta_first_slide": t_sl, "slide_minus_onset": t_sl - t_on,
                     "ke_max": float(fin.max()) if fin.size else float("nan")})
    cols = ["run", "n_frames", "theta_end", "n_onsets", "theta_first_onset", "theta_first_slide",
            "slide_minus_onset", "ke_max"]
    return pd.DataFrame(rows, columns=cols)


def precursor_count(theta_deg, onset, avalanching, theta_slide: float) -> int:
    """Precursor events of one run: its onsets whose avalanche ends before its first slide.

    theta_deg, onset, avalanching: one run's frames in order (deg, bool, bool); theta_slide: its
    first slide (deg; NaN: none). An onset counts when the avalanching stretch it starts ends
    (its last frame) at theta < theta_slide: an avalanche still running when the slide begins is
    the slide's own start. With no slide every onset counts.
    """
    th = np.asarray(theta_deg, dtype=float)
    on = np.asarray(onset, dtype=bool)
    av = np.asarray(avalanching, dtype=bool)
    if not (th.shape == on.shape == av.shape):
        raise ValueError("precursor_count: theta_deg, onset and avalanching differ in length")
    av = av | on
    idx = np.flatnonzero(on)
    if not np.isfinite(theta_slide):
        return int(idx.size)
    starts, ends = stretches(av)
    last = np.empty(th.size, dtype=int)                # last frame of the stretch holding k
    for s, e in zip(starts, ends):
        last[s:e] = e - 1
    return int(sum(th[last[i]] < theta_slide - 1e-9 for i in idx))
