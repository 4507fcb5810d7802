"""Fig. 2 -- the avalanche criterion and the generalized isostaticity diagram (paper Fig. 2).

(a) Probability density of the kinetic energy per mobile grain over all frames and runs
    (log-binned, :func:`tiltpile.analysis.log_binned_density`), with the threshold where it leaves
    the power law of the quiet region (:func:`power_law_departure`, estimator below).
(b) Probability density of the fraction of contacts lost between successive frames (log-binned;
    frames losing no contact cannot be placed on the log axis but are in the normalisation), with
    the avalanche cutoff (2% by default) that separates quiet and avalanching frames.
(c) delta z_gen = z - 3 - n_m of the bulk against theta for a sample run, avalanching frames
    shaded.
(d) Probability density of (z, n_m) over all frames (:func:`tiltpile.analysis.density_2d`), with
    the sample run's trace (quiet black, avalanching red) and the marginal line z = 3 + n_m.

Kinetic-energy threshold (paper: "the value above which the distribution escapes the power law
reported in the quiet region"): a straight line log10 P = a + b log10 E is fitted, weighted by
sqrt(count) (Poisson error of log P), to the log bins whose centres lie between two quantiles of
the quiet frames' energies (default 30% and 80%: above the rest peak of the freshly deposited
pile, below the energies of the frames just before failure); going up from the fitted range, the
threshold is the lower edge of the first bin from which ``n_consecutive`` successive bins all lie
off the line by more than ``factor`` (empty bins count as off).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from tiltpile.analysis import stats as _st
from tiltpile.analysis.avalanche import (SPACING_LIMIT, ResolutionWarning, frame_spacing_check,
                                         onset_robustness_ensemble, stretches)

from . import fig3, style

NAME = "fig2_avalanche_criterion"


def power_law_departure(density: pd.DataFrame, fit_lo: float, fit_hi: float,
                        factor: float = 2.0, n_consecutive: int = 2,
                        min_count: int = 3) -> dict:
    """Fit a power law to part of a log-binned density and find where the density leaves it.

    density: a :func:`tiltpile.analysis.log_binned_density` table (left, right, center, count,
    density). The fit: least squares of log10(density) on log10(center) over the bins with
    fit_lo <= center <= fit_hi and count >= min_count, weights sqrt(count). The departure: the
    first bin with center > fit_hi such that it and the next ``n_consecutive - 1`` bins (fewer at
    the end of the table) all differ from the fit by more than ``factor`` (|log10 ratio| >
    log10 factor; empty bins always differ).

    Returns dict slope, intercept (log10 P = intercept + slope log10 x), n_fit_bins, fit_lo,
    fit_hi, threshold (left edge of the departing bin; NaN if none or if fewer than 2 bins were
    fitted), threshold_center.
    """
    out = {"slope": np.nan, "intercept": np.nan, "n_fit_bins": 0, "fit_lo": float(fit_lo),
           "fit_hi": float(fit_hi), "threshold": np.nan, "threshold_center": np.nan}
    if len(density) == 0 or not (np.isfinite(fit_lo) and np.isfinite(fit_hi)):
        return out
    c = density["center"].to_numpy(float)
    n = density["count"].to_numpy(float)
    p = density["density"].to_numpy(float)
    fit = (c >= fit_lo) & (c <= fit_hi) & (n >= min_count)
    out["n_fit_bins"] = int(fit.sum())
    if fit.sum() < 2:
        return out
    slope, intercept = np.polyfit(np.log10(c[fit]), np.log10(p[fit]), 1, w=np.sqrt(n[fit]))
    out.update(slope=float(slope), intercept=float(intercept))
    with np.errstate(divide="ignore"):
        off = np.abs(np.log10(p) - (intercept + slope * np.log10(c))) > np.log10(factor)
    off |= n == 0
    above = np.flatnonzero(c > fit_hi)
    for i in above:
        j = min(i + max(1, int(n_consecutive)), c.size)
        if off[i:j].all():
            out.update(threshold=float(density["left"].iloc[i]), threshold_center=float(c[i]))
            break
    return out


def first_onsets(frames: pd.DataFrame, seeds) -> np.ndarray:
    """theta of the first avalanche onset of each run (NaN without onset), in the order of seeds."""
    on = frames[frames["onset"].astype(bool)].sort_values(["run", "frame"], kind="stable")
    first = on.groupby("run")["theta_deg"].first()
    return np.array([float(first.get(s, np.nan)) for s in seeds])


def _stats(x) -> dict:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return {"mean": float(x.mean()) if x.size else np.nan,
            "std": float(x.std(ddof=1)) if x.size > 1 else np.nan,
            "min": float(x.min()) if x.size else np.nan,
            "max": float(x.max()) if x.size else np.nan, "n": int(x.size)}


def _max_abs(x) -> float:
    x = np.abs(np.asarray(x, dtype=float))
    x = x[np.isfinite(x)]
    return float(x.max()) if x.size else np.nan


def compute(ens, sample_seed: int | None = None, ke_column: str = "ke_trans",
            ke_bins_per_decade: int = 5, ke_fit_quantiles=(0.3, 0.8), ke_factor: float = 2.0,
            ke_consecutive: int = 2, lost_bins_per_decade: int = 5, zn_bins=30,
            robustness_cutoffs=(0.01, 0.02, 0.03, 0.04), max_shift: int = 10
            ) -> tuple[dict, dict]:
    """Numbers and plot data of Fig. 2 (module docstring).

    sample_seed: run of panels c, d (None: the first run with an onset); ke_column: "ke_trans"
    or "ke_rot"; ke_bins_per_decade, ke_fit_quantiles, ke_factor, ke_consecutive: the KE density
    and threshold estimator (:func:`power_law_departure`); lost_bins_per_decade: panel b;
    zn_bins: bins of the (z, n_m) density (numpy.histogram2d); robustness_cutoffs, max_shift:
    :func:`tiltpile.analysis.onset_robustness_ensemble` against the ensemble's cutoff.

    numbers:
      cutoff                       the avalanche cutoff on the lost fraction
      theta_m_per_run              theta of each run's first onset (deg, seeds in ens.seeds
                                   order; null without onset)
      theta_m_mean, _std (ddof 1), _min, _max, n_runs_with_onset
      n_onsets                     all onsets of all runs
      avalanching_fraction         fraction of all frames that are avalanching
      z_quiet_mean, n_m_quiet_mean, dz_gen_quiet_mean   over quiet frames (bulk)
      quiet_below_fraction         fraction of quiet frames with delta z_gen < 0
      ke_column, ke_threshold      KE per grain where the density leaves the quiet power law
      ke_slope, ke_fit_range       fitted exponent and the fitted KE range
      ke_threshold_avalanching_above, ke_threshold_quiet_above
                                   fraction of avalanching / quiet frames with KE above the
                                   threshold (how well the KE criterion agrees with the
                                   lost-contact one)
      lost_zero_fraction           frames that lose no contact (not on the log axis of b)
      onset_shift_max_frames       max |shift| of matched onsets over the robustness cutoffs
      onset_shift_max_frames_by_cutoff   the same per cutoff
      onset_shift_max_deg          max |shift| in degrees
      first_onset_shift_max_frames max |shift| of each run's first onset
      onset_unmatched_fraction     (onset, cutoff) pairs with no onset within max_shift frames
      onset_cutoffs_unresolved     robustness cutoffs that the frame spacing does not resolve in
                                   some run (:func:`tiltpile.analysis.frame_spacing_check`)
      sample_seed
    """
    p = fig3.analysis_params(ens)
    cutoff = float(p["cutoff"])
    f = ens.frames.sort_values(["run", "frame"], kind="stable")
    av = f["avalanching"].to_numpy(bool)
    numbers: dict = {"cutoff": cutoff}
    d: dict = {"cutoff": cutoff}

    th = first_onsets(f, ens.seeds)
    st = _stats(th)
    numbers.update(theta_m_per_run=th, theta_m_mean=st["mean"], theta_m_std=st["std"],
                   theta_m_min=st["min"], theta_m_max=st["max"], n_runs_with_onset=st["n"],
                   n_onsets=int(f["onset"].astype(bool).sum()),
                   avalanching_fraction=float(av.mean()) if av.size else np.nan)
    q = f[~av]
    dzq = q["dz_gen"].to_numpy(float)
    dzq = dzq[np.isfinite(dzq)]
    numbers.update(z_quiet_mean=_stats(q["z"])["mean"], n_m_quiet_mean=_stats(q["n_m"])["mean"],
                   dz_gen_quiet_mean=float(dzq.mean()) if dzq.size else np.nan,
                   quiet_below_fraction=float((dzq < 0).mean()) if dzq.size else np.nan)

    # (a) kinetic energy
    ke = f[ke_column].to_numpy(float)
    ke_dens = _st.log_binned_density(ke, ke_bins_per_decade)
    kq = ke[~av & np.isfinite(ke) & (ke > 0)]
    lo, hi = (np.quantile(kq, ke_fit_quantiles) if kq.size else (np.nan, np.nan))
    dep = power_law_departure(ke_dens, lo, hi, ke_factor, ke_consecutive)
    thr = dep["threshold"]
    ok = np.isfinite(ke)
    above = ke > thr if np.isfinite(thr) else np.zeros_like(ok)
    numbers.update(ke_column=ke_column, ke_threshold=thr, ke_slope=dep["slope"],
                   ke_fit_range=[dep["fit_lo"], dep["fit_hi"]],
                   ke_threshold_avalanching_above=float(above[av & ok].mean())
                   if (av & ok).any() and np.isfinite(thr) else np.nan,
                   ke_threshold_quiet_above=float(above[~av & ok].mean())
                   if (~av & ok).any() and np.isfinite(thr) else np.nan)
    d.update(ke_density=ke_dens, ke_fit=dep, ke_column=ke_column)

    # (b) lost fraction
    lost = _st.log_binned_density(f["lost_fraction"], lost_bins_per_decade)
    nt = lost.attrs.get("n_total", 0)
    numbers["lost_zero_fraction"] = lost.attrs["n_nonpositive"] / nt if nt else np.nan
    d["lost_density"] = lost

    # robustness of the onsets to the cutoff. The cutoffs are varied on purpose, so the
    # library's ResolutionWarning (frames too far apart for a cutoff: the quiet frames' median
    # lost fraction exceeds half of it) is not issued here but reported: onset_cutoffs_unresolved
    # lists the cutoffs it flags in at least one run.
    unresolved = sorted({float(c) for c in robustness_cutoffs for _, g in f.groupby("run")
                         if frame_spacing_check(g["lost_fraction"].to_numpy(float), c,
                                                warn=False) > SPACING_LIMIT})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResolutionWarning)
        rob = onset_robustness_ensemble(f, cutoffs=robustness_cutoffs, reference=cutoff,
                                        max_shift=max_shift, merge_gap=p["merge_gap"])
    numbers["onset_cutoffs_unresolved"] = unresolved
    if len(rob):
        by_cut = {f"{c:g}": _max_abs(g["shift_frames"]) for c, g in rob.groupby("cutoff")}
        first = rob[rob["onset"] == 0]
        numbers.update(onset_shift_max_frames=_max_abs(rob["shift_frames"]),
                       onset_shift_max_frames_by_cutoff=by_cut,
                       onset_shift_max_deg=_max_abs(rob["shift_deg"]),
                       first_onset_shift_max_frames=_max_abs(first["shift_frames"]),
                       onset_unmatched_fraction=float(rob["shift_frames"].isna().mean()))
    else:
        numbers.update(onset_shift_max_frames=np.nan, onset_shift_max_frames_by_cutoff={},
                       onset_shift_max_deg=np.nan, first_onset_shift_max_frames=np.nan,
                       onset_unmatched_fraction=np.nan)

    # (c), (d) sample run and the (z, n_m) density
    seed = ens.sample_seed(sample_seed)
    numbers["sample_seed"] = seed
    d["sample"] = f[f["run"] == seed][["frame", "theta_deg", "z", "n_m", "dz_gen",
                                        "avalanching"]].reset_index(drop=True)
    try:
        d["zn_density"] = _st.density_2d(f["z"], f["n_m"], bins=zn_bins)
    except _st.InsufficientDataError:
        d["zn_density"] = None
    d["sample_seed"] = seed
    return numbers, d


def plot(data: dict, numbers: dict):
    """Panels a-d (module docstring)."""
    from matplotlib.colors import LogNorm
    height, gkw = fig3.stacked_layout([1.45, 1.45], [0.5], top_in=0.05, bottom_in=0.38,
                                      left=0.14, right=0.97)
    fig, axs = style.figure(2, 2, height=height, gridspec_kw=dict(gkw, wspace=0.42))
    (a, b), (c, dd) = axs

    # (a) kinetic energy
    ke, dep = data["ke_density"], data["ke_fit"]
    if len(ke):
        nz = ke["count"].to_numpy() > 0
        a.loglog(ke["center"][nz], ke["density"][nz], ls="none", marker="o", ms=2.5,
                 color=style.COLORS["quiet"])
        xc = ke["center"].to_numpy(float)
        yc = ke["density"].to_numpy(float)
        if np.isfinite(dep["slope"]):
            x_hi = dep["threshold"] * 3 if np.isfinite(dep["threshold"]) else xc[-1]
            x = np.array([dep["fit_lo"] / 30, x_hi])
            a.loglog(x, 10 ** (dep["intercept"] + dep["slope"] * np.log10(x)), ls="--", lw=0.8,
                     color=style.COLORS["fit"], label=rf"$\propto E^{{{dep['slope']:.2f}}}$")
            a.axvspan(dep["fit_lo"], dep["fit_hi"], color=style.COLORS["guide"], alpha=0.15, lw=0)
        if np.isfinite(dep["threshold"]):
            y = 10 ** (dep["intercept"] + dep["slope"] * np.log10(dep["threshold"]))
            a.annotate("", xy=(dep["threshold"], y * 2), xytext=(dep["threshold"], y * 300),
                       arrowprops=dict(arrowstyle="-|>", color=style.COLORS["avalanche"], lw=1.2))
            a.plot([], [], color=style.COLORS["avalanche"], lw=1.2,
                   label=f"threshold {dep['threshold']:.1e}".replace("e-0", "e-"))
        a.legend(loc="lower left", handlelength=1.5)
    unit = {"ke_trans": r"$E_t$", "ke_rot": r"$E_r$"}.get(data["ke_column"], "E")
    a.set_xlabel(unit + r" per grain ($\rho g d^3$)")
    a.set_ylabel(r"$P($" + unit + r"$)$")
    style.panel_label(a, "a", x=0.88)

    # (b) lost fraction
    lo = data["lost_density"]
    if len(lo):
        nz = lo["count"].to_numpy() > 0
        qq = lo["center"].to_numpy() <= data["cutoff"]
        for sel, col in ((qq, style.COLORS["quiet"]), (~qq, style.COLORS["avalanche"])):
            b.loglog(lo["center"][nz & sel], lo["density"][nz & sel], ls="none", marker="s", ms=2.5,
                     color=col)
        b.loglog(lo["center"][nz], lo["density"][nz], ls="-", lw=0.5, color=style.COLORS["guide"],
                 zorder=0)
    b.axvline(data["cutoff"], color=style.COLORS["avalanche"], lw=1.0,
              label=f"cutoff {100 * data['cutoff']:g}%")
    if len(lo) and (lo["count"] > 0).any():
        nzl = lo[lo["count"] > 0]
        b.set_xlim(10 ** np.floor(np.log10(nzl["left"].min()) + 1e-9),
                   10 ** np.ceil(np.log10(nzl["right"].max()) - 1e-9))
    b.set_xlabel("fraction of contacts lost")
    b.set_ylabel("probability density")
    b.legend(loc="lower left", handlelength=1.5)
    style.panel_label(b, "b", x=0.88)
    from matplotlib.ticker import NullFormatter
    for ax in (a, b):
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())

    # (c) delta z_gen of the sample run
    s = data["sample"]
    th = s["theta_deg"].to_numpy(float)
    dth = float(np.median(np.diff(th))) if th.size > 1 else 0.1
    for i, j in zip(*stretches(s["avalanching"].to_numpy(bool))):
        c.axvspan(th[i] - dth / 2, th[j - 1] + dth / 2, color=style.COLORS["avalanche_shade"],
                  alpha=0.45, lw=0)
    c.axhline(0, color=style.COLORS["marginal"], lw=0.8)
    c.plot(th, s["dz_gen"], color=style.COLORS["quiet"], lw=0.7)
    c.set_xlabel(r"$\theta$ (deg)")
    c.set_ylabel(r"$\delta z^{gen} = z - 3 - n_m$")
    c.set_xlim(th.min() if th.size else 0, th.max() if th.size else 1)
    dzs = s["dz_gen"].to_numpy(float)
    dzs = dzs[np.isfinite(dzs)]
    if dzs.size:
        r = max(dzs.max(), 0.0) - min(dzs.min(), 0.0)
        c.set_ylim(min(dzs.min(), 0.0) - 0.05 * r, max(dzs.max(), 0.0) + 0.25 * r)
    style.panel_label(c, "c")
    c.text(0.97, 0.96, f"run {data['sample_seed']}", transform=c.transAxes, ha="right", va="top",
           fontsize=6.5)

    # (d) (z, n_m) density and the sample trace
    zd = data["zn_density"]
    if zd is not None:
        h, xe, ye = zd
        hm = np.ma.masked_less_equal(h.T, 0)
        if hm.count():
            dd.pcolormesh(xe, ye, hm, cmap="Greys", norm=LogNorm(vmin=hm.min(), vmax=hm.max() * 3),
                          rasterized=True)
        dd.set_xlim(xe[0], xe[-1])
        dd.set_ylim(ye[0], ye[-1])
    avs = s["avalanching"].to_numpy(bool)
    dd.plot(s["z"], s["n_m"], color=style.COLORS["guide"], lw=0.3, zorder=2)
    dd.plot(s["z"][~avs], s["n_m"][~avs], ls="none", marker="o", ms=1.6, mew=0,
            color=style.COLORS["quiet"], zorder=3, label="quiet")
    dd.plot(s["z"][avs], s["n_m"][avs], ls="none", marker="o", ms=2.0, mew=0,
            color=style.COLORS["avalanche"], zorder=4, label="avalanching")
    x0, x1 = dd.get_xlim()
    dd.plot([x0, x1], [x0 - 3.0, x1 - 3.0], color=style.COLORS["marginal"], lw=1.0,
            label="marginal", zorder=5)
    dd.set_xlim(x0, x1)
    y0, y1 = dd.get_ylim()
    dd.set_ylim(min(y0, 0.0), y0 + (y1 - y0) * 1.45)          # room for the legend
    dd.set_xlabel(r"$z$")
    dd.set_ylabel(r"$n_m$")
    dd.legend(loc="upper right", handlelength=1.2, markerscale=1.8)
    style.panel_label(dd, "d")
    return fig
