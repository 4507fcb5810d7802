"""The health summary of a run: its per-frame flags judged against the warn limits of ``[health]``.

The simulator records, for every frame, the worst step since the previous frame (``max_overlap``,
``energy_gain``) and how many steps were flagged (``cap_hits``, ``missed``); ``sim.protocol``
stops a run past the stop limits. This module turns the recorded columns of a whole run into one
summary dict (``summarize``) -- plain ints, floats and strings, for the run file's ``/health``
attrs, ``runner.simulate``'s return value and the ensemble manifest -- whose ``warnings`` list says,
for each warn limit passed, how often, how badly, from which frame on, and what to change.
``runner.simulate`` issues them as one ``RuntimeWarning``.

Limits (``config.HealthConfig``; docs/health.md):

* overlap: frames whose largest overlap exceeds ``overlap_warn``; the deposition's largest
  overlap against the same limit;
* energy: tilt frames (frame 0, whose settling steps re-solve the deposited pile from
  ``deposition_tol`` to ``solver.tol``, is recorded as ``settle_energy_gain`` but not judged) with
  a step whose kinetic energy gain beyond the work of gravity exceeds ``energy_warn`` per mobile
  grain (spurious elasticity: unconverged solver, overlaps pushed out);
* iteration cap: the fraction of the steps at ``solver.tol`` (frame 0's settling steps and the tilt)
  that hit ``solver.max_iter``, against ``cap_hit_warn_fraction``;
* missed: any tilt-phase step in which a grain moved farther than ``alert / 2`` since the contact
  list was built (no limit: always reported; deposition's are counted, not warned about).
"""

from __future__ import annotations

import math

import numpy as np

COLUMNS = ("theta_deg", "max_overlap", "energy_gain", "cap_hits", "missed")


def _first(mask: np.ndarray, theta: np.ndarray) -> str:
    i = int(np.argmax(mask))
    return f"first at frame {i}, theta = {theta[i]:.2f} deg"


def summarize(columns: dict, deposition: dict, config, n_mobile: int) -> dict:
    """Health summary of a run from its per-frame ``columns`` (``COLUMNS``), ``deposition``
    attrs, ``config`` (a ``config.Config``) and number of mobile grains.

    Frame 0 is the settled pile (``protocol.rest_steps`` steps since deposition), every later
    frame ``protocol.frame_every`` tilt steps.

    Returns a dict: frames, steps_at_tol, cap_hits, cap_hit_fraction, max_overlap,
    overlap_frames, max_energy_gain (per mobile grain, tilt frames), energy_frames,
    settle_energy_gain (frame 0, per mobile grain), missed_steps, missed_frames,
    deposition_max_overlap, deposition_missed, warnings (list of str).
    """
    h, proto, solver = config.health, config.protocol, config.solver
    theta = np.asarray(columns["theta_deg"], float)
    nf = theta.size
    overlap = np.asarray(columns["max_overlap"], float)
    gain = np.asarray(columns["energy_gain"], float) / max(n_mobile, 1)
    caps = np.asarray(columns["cap_hits"], np.int64)
    missed = np.asarray(columns["missed"], np.int64)
    steps = proto.rest_steps + max(nf - 1, 0) * proto.frame_every if nf else 0
    cap_hits = int(caps.sum())
    frac = cap_hits / steps if steps else 0.0
    over = overlap > h.overlap_warn
    tilt_gain = np.where(np.arange(nf) > 0, gain, np.nan)
    hot = np.isfinite(tilt_gain) & (tilt_gain > h.energy_warn)
    miss = missed > 0
    dep_overlap = float(deposition.get("max_overlap", 0.0))
    s = {
        "frames": int(nf), "steps_at_tol": int(steps), "cap_hits": cap_hits,
        "cap_hit_fraction": float(frac),
        "max_overlap": float(overlap.max()) if nf else 0.0, "overlap_frames": int(over.sum()),
        "max_energy_gain": (float(np.nanmax(tilt_gain)) if np.isfinite(tilt_gain).any()
                            else math.nan),
        "energy_frames": int(hot.sum()),
        "settle_energy_gain": float(gain[0]) if nf and np.isfinite(gain[0]) else math.nan,
        "missed_steps": int(missed.sum()), "missed_frames": int(miss.sum()),
        "deposition_max_overlap": dep_overlap,
        "deposition_missed": int(deposition.get("missed", 0)),
    }
    w = []
    if over.any():
        w.append(f"{s['overlap_frames']} of {nf} frames overlap more than health.overlap_warn = "
                 f"{h.overlap_warn:g} d (largest {s['max_overlap']:.3g} d, {_first(over, theta)}): "
                 "reduce solver.dt")
    if dep_overlap > h.overlap_warn:
        w.append(f"deposition overlapped by {dep_overlap:.3g} d > health.overlap_warn = "
                 f"{h.overlap_warn:g} d: reduce solver.dt")
    if hot.any():
        w.append(f"{s['energy_frames']} of {nf - 1} tilt frames have a step in which the kinetic energy grew "
                 f"more than gravity did work, by up to {s['max_energy_gain']:.3g} m g d per grain "
                 f"> health.energy_warn = {h.energy_warn:g} ({_first(hot, theta)}): contacts "
                 "create energy (spurious elasticity); tighten solver.tol / raise solver.max_iter, "
                 "or reduce solver.dt if overlaps are flagged too")
    if frac > h.cap_hit_warn_fraction:
        w.append(f"{cap_hits} of {steps} steps at solver.tol ({frac:.1%}) hit solver.max_iter = "
                 f"{solver.max_iter} > health.cap_hit_warn_fraction = {h.cap_hit_warn_fraction:g}: "
                 "the cap, not solver.tol, sets the accuracy; raise solver.max_iter")
    if miss.any():
        w.append(f"{s['missed_steps']} steps in {s['missed_frames']} frames moved a grain farther "
                 f"than solver.alert / 2 since the contact list was built ({_first(miss, theta)}): "
                 "contacts may have been missed; reduce solver.dt or raise solver.alert")
    s["warnings"] = w
    return s


def warning_message(summary: dict, label: str = "") -> str | None:
    """One text for all of a summary's warnings (None when there are none)."""
    if not summary["warnings"]:
        return None
    head = f"tiltpile run {label}: " if label else "tiltpile run: "
    return head + f"{len(summary['warnings'])} health warning(s): " + "; ".join(summary["warnings"])
