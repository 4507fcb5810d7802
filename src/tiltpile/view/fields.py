"""Per-frame fields of a run as the paper's analysis defines them, for export and movies.

Everything here is computed by :mod:`tiltpile.analysis` with its default parameters
(``DEFAULT_PARAMS``) and the run's friction, exactly as the observables tables are:

``n_active``      (N,) int    active contacts of each grain (f_n > 0, with any partner:
                              grains, fixed grains, walls); rattlers are not removed
``n_mobilized``   (N,) int    its fully mobilized active contacts (solver sliding flag)
``cluster``       (N,) int    critical-cluster id (0 = largest), -1 in no cluster
``failing``       (N,) bool   lost a contact since the previous stored frame (frame k - 1 -> k;
                              False at frame 0)
``failing_next``  (N,) bool   loses a contact by the next stored frame (k -> k + 1; False at the
                              last frame): the "failing" grains of the paper's Fig. 3, which are
                              compared with the clusters of frame k

and per contact of the frame (contacts without a mobile grain dropped, as in the analysis):
``pair`` (C, 2), ``force`` (C, 2) [f_n, f_t], ``status`` (C,), ``active``, ``mobilized`` (C,)
bool. Frames are 0-based indices of the stored frames; a frame selection is a Python slice.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from tiltpile.analysis import DEFAULT_PARAMS
from tiltpile.analysis import contacts as _ct
from tiltpile.analysis import observables as _ob

GRAIN_FIELDS = ("n_active", "n_mobilized", "cluster", "failing", "failing_next")


def parse_frames(text: str | None, n_frames: int) -> list[int]:
    """Frame indices of ``START:STOP:STEP`` (Python slice syntax, each part optional; a single
    integer selects one frame; negative indices count from the end). None: every frame.

    Raises ValueError with the reason on bad text or an empty selection."""
    if text is None or text.strip() in ("", ":"):
        return list(range(n_frames))
    parts = text.split(":")
    if len(parts) > 3:
        raise ValueError(f"--frames {text!r}: expected START:STOP:STEP")
    try:
        vals = [int(p) if p.strip() else None for p in parts]
    except ValueError:
        raise ValueError(f"--frames {text!r}: START, STOP and STEP must be integers") from None
    if len(parts) == 1:
        k = vals[0]
        if not -n_frames <= k < n_frames:
            raise ValueError(f"--frames {text!r}: frame {k} out of range, the run has {n_frames} frames")
        return [k % n_frames]
    if len(vals) == 3 and vals[2] is not None and vals[2] <= 0:
        raise ValueError(f"--frames {text!r}: STEP must be a positive integer")
    sel = list(range(n_frames))[slice(*vals)]
    if not sel:
        raise ValueError(f"--frames {text!r} selects no frame of the {n_frames}")
    return sel


def analysis_settings(run) -> dict:
    """Friction of grain and wall contacts (from the run's config) and the analysis defaults."""
    scene = run.config.get("scene", {}) if isinstance(run.config, dict) else {}
    mu = float(scene.get("mu", 0.5))
    p = DEFAULT_PARAMS
    return {"mu": mu, "mu_wall": float(scene.get("mu_wall", mu)), "eps": p["eps"],
            "link": p["link"], "cluster_region": p["cluster_region"],
            "ray_spacing": p["ray_spacing"], "touch_tol": p["touch_tol"], "lost_gap": p["lost_gap"]}


class FrameFields:
    """Fields of the frames of one open run (:func:`tiltpile.store.open_run`), computed on demand.

    ``fields(k)`` returns a dict with the frame's scalars (frame, step, time, theta_deg), its
    arrays (position, velocity, omega; radius and fixed of the run) and the fields of the module
    docstring. The contacts of the last few frames are kept, so walking frames in order
    analyses each frame once.
    """

    def __init__(self, run, keep: int = 4):
        self.run = run
        self.settings = analysis_settings(run)
        self.radius = np.asarray(run.radius, dtype=float)
        self.fixed = np.asarray(run.fixed, dtype=bool)
        self.n = self.fixed.size
        self.box_length = float(run.box_length)
        self._cache: OrderedDict[int, dict] = OrderedDict()
        self._keep = keep

    def contacts(self, k: int) -> dict:
        """:func:`tiltpile.analysis.observables.frame_contacts` of frame k, plus its position."""
        if k in self._cache:
            self._cache.move_to_end(k)
            return self._cache[k]
        s = self.settings
        pos = np.asarray(self.run.position(k), dtype=float)
        pair, force, status = self.run.contacts(k)
        fc = _ob.frame_contacts(self.radius, self.fixed, self.box_length, pos, pair, force, status,
                                mu=s["mu"], mu_wall=s["mu_wall"], eps=s["eps"], link=s["link"],
                                cluster_region=s["cluster_region"], ray_spacing=s["ray_spacing"],
                                touch_tol=s["touch_tol"])
        fc["position"] = pos
        self._cache[k] = fc
        while len(self._cache) > self._keep:
            self._cache.popitem(last=False)
        return fc

    def _failing(self, a: int, b: int) -> np.ndarray:
        """Mobile grains at an end of a contact active at frame a and not at frame b."""
        prev, cur = self.contacts(a), self.contacts(b)
        lost = _ob.lost_between(prev, cur, self.n, self.radius, self.box_length,
                                self.settings["lost_gap"])
        return _ct.failing_grains(self.n, prev["pair"], lost, self.fixed)

    def fields(self, k: int) -> dict:
        run = self.run
        nf = int(run.n_frames)
        if not 0 <= k < nf:
            raise IndexError(f"frame {k} out of range: the run has {nf} frames")
        no = np.zeros(self.n, dtype=bool)
        failing = self._failing(k - 1, k) if k > 0 else no
        fc = self.contacts(k)
        failing_next = self._failing(k, k + 1) if k + 1 < nf else no
        return {
            "frame": k, "step": int(run.step[k]), "time": float(run.time[k]),
            "theta_deg": float(run.theta_deg[k]), "ke": float(run.ke[k]),
            "position": fc["position"], "velocity": np.asarray(run.velocity(k), dtype=float),
            "omega": np.asarray(run.omega(k), dtype=float), "radius": self.radius,
            "fixed": self.fixed, "box_length": self.box_length,
            "n_active": _ct.contact_counts(self.n, fc["pair"], fc["active"]),
            "n_mobilized": _ct.contact_counts(self.n, fc["pair"], fc["mobilized"]),
            "cluster": fc["labels"], "failing": failing, "failing_next": failing_next,
            "pair": fc["pair"], "force": fc["force"],
            "status": (fc["status"] if fc["status"] is not None
                       else np.zeros(len(fc["pair"]), dtype=np.int8)),
            "active": fc["active"], "mobilized": fc["mobilized"],
        }


def contact_segments(pair: np.ndarray, position: np.ndarray, box_length: float) -> np.ndarray:
    """End points (C, 2, 2) of each contact drawn as a line: centre to centre for two grains,
    centre to the touching point on the floor (y = 0) or on a side wall (x = 0, x = L)."""
    pair = np.asarray(pair).reshape(-1, 2)
    i, j = pair[:, 0], pair[:, 1]
    a = position[i]
    b = position[np.maximum(j, 0)].copy()
    fl, le, ri = j == _ct.WALL_FLOOR, j == _ct.WALL_LEFT, j == _ct.WALL_RIGHT
    b[fl, 1] = 0.0
    b[fl, 0] = a[fl, 0]
    b[le, 0] = 0.0
    b[le, 1] = a[le, 1]
    b[ri, 0] = box_length
    b[ri, 1] = a[ri, 1]
    return np.stack([a, b], axis=1)
