"""One frame of another code's data, checked and turned into a run file's frame.

A reader (``lammps``, ``plain``) yields ``RawFrame``s in the source's units and grain ids;
``Converter`` checks each against the format (docs/import.md) and the frames before it, and
gives the ``sim.protocol.Frame`` the run file's writer appends: grains ordered by id, lengths in
d, contacts as pairs of grain indices (i < j; walls -1 floor, -2 left, -3 right) sorted as the
engines sort them, the status of each contact from the source's sliding flag or the Coulomb
test |f_t| >= mu f_n (1 - eps), the kinetic energy and the largest overlap computed from the
frame. Every refusal is an ``InputError`` of one line naming the field and the frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tiltpile.config import ConfigError
from tiltpile.sim.protocol import Frame

WALL_IDS = {"floor": -1, "left": -2, "right": -3}
DEFAULT_EPS = 1e-4   # the Coulomb test's tolerance when the source flags no sliding contact
BACKWARDS_DEG = 1e-9  # an angle lower than the previous frame's by more than this goes backwards
MEAN_DIAMETER = (0.5, 2.0)  # the mobile grains' mean diameter must lie here [d]: lengths in d


class InputError(ConfigError):
    """Input that cannot be imported: one line naming the field, the frame and the file."""


@dataclass
class Units:
    """The source's units, each in the run file's (docs/import.md): a length of the source is
    ``length`` d, a time ``time`` sqrt(d/g), a force ``force`` m g."""

    length: float = 1.0
    time: float = 1.0
    force: float = 1.0


@dataclass
class RawFrame:
    """One frame as read, in the source's units and ids (the fields of docs/import.md).

    Grains: ``id`` (N,) integers >= 0, ``position`` (N, 2), ``radius`` (N,), ``fixed`` (N,) bool,
    ``velocity`` (N, 2), ``omega`` (N,) and ``rotation`` (N,) or None where the source has
    none. Contacts: ``id1``, ``id2`` (C,) grain ids, or in ``id2`` (or ``id1``) a wall -1, -2,
    -3; ``fn``, ``ft`` (C,); ``sliding`` (C,) bool or None. ``where`` names the frame's file."""

    where: str
    step: int
    time: float          # NaN: not given
    theta_deg: float
    id: np.ndarray
    position: np.ndarray
    radius: np.ndarray
    fixed: np.ndarray
    velocity: np.ndarray | None
    omega: np.ndarray | None
    rotation: np.ndarray | None
    id1: np.ndarray
    id2: np.ndarray
    fn: np.ndarray
    ft: np.ndarray
    sliding: np.ndarray | None


def label(k: int, step, where: str) -> str:
    """How a message names a frame: ``frame K (step S, FILE)``."""
    return f"frame {k} (step {step}, {where})"


def finite(values, field: str, where: str, ids=None, what: str = "grain id",
           columns: tuple | None = None) -> np.ndarray:
    """``values`` as float64; InputError naming the field (``columns``: the names of a 2-column
    field's columns), the frame and the first row (its id) that is NaN or infinite."""
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {field} must hold numbers") from None
    bad = ~np.isfinite(a)
    if bad.any():
        if a.ndim == 0:
            raise InputError(f"{where}: {field} is {a} (not a finite number)")
        rows = bad.reshape(a.shape[0], -1)
        k = int(np.flatnonzero(rows.any(axis=1))[0])
        c = int(np.flatnonzero(rows[k])[0])
        name = columns[c] if columns is not None else field
        row = f" of {what} {int(ids[k])}" if ids is not None else f" in row {k}"
        raise InputError(f"{where}: {name}{row} is {a.reshape(a.shape[0], -1)[k, c]} (not a "
                         "finite number)")
    return a


def integers(values, field: str, where: str) -> np.ndarray:
    """``values`` as int64; InputError naming the field and the first value that is not an
    integer."""
    a = np.asarray(values)
    if a.dtype.kind in "iu" or (a.size == 0 and a.dtype.kind in "fO"):
        return a.astype(np.int64)
    if a.dtype.kind == "b" or a.dtype.kind not in "f":
        raise InputError(f"{where}: {field} must hold integers, not {a.dtype}")
    bad = ~np.isfinite(a) | (a != np.round(a)) | (np.abs(a) > 2**53)
    if bad.any():
        raise InputError(f"{where}: {field} holds {a[bad][0].item()!r}, not an integer (row "
                         f"{int(np.flatnonzero(bad)[0])})")
    return a.astype(np.int64)


def flags(values, field: str, where: str) -> np.ndarray:
    """``values`` (bool, or numbers 0 / 1) as bool; InputError for anything else."""
    a = np.asarray(values)
    if a.dtype.kind == "b":
        return a
    if a.dtype.kind in "iuf":
        bad = ~np.isin(a, (0, 1))
        if bad.any():
            raise InputError(f"{where}: {field} holds {a[bad][0].item()!r}; it must be 0 or 1 (or "
                             f"true / false), row {int(np.flatnonzero(bad)[0])}")
        return a.astype(bool)
    raise InputError(f"{where}: {field} must be 0 / 1 or true / false, not {a.dtype}")


def contact_order(i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """The order the engines store a frame's contacts in: by i, then by j, walls after grains
    (floor, left, right)."""
    key = i * (n + 3) + np.where(j >= 0, j, n - 1 - j)
    return np.argsort(key, kind="stable")


class Converter:
    """Check frames in order and turn them into run-file frames (module docstring).

    box_length [d], mu and mu_wall (the Coulomb test and nothing else), eps (None: the source
    flags the sliding contacts; a frame without that flag is then refused), units (``Units``):
    the import's settings. ``convert(raw)`` gives the next ``Frame``; the first frame fixes the
    grains (ids, radii, fixed), which every later one must repeat."""

    def __init__(self, box_length: float, mu: float, mu_wall: float | None = None,
                 eps: float | None = DEFAULT_EPS, units: Units | None = None):
        self.units = units or Units()
        self.box_length = float(box_length) / self.units.length
        self.mu = float(mu)
        self.mu_wall = self.mu if mu_wall is None else float(mu_wall)
        self.eps = eps
        self.k = 0
        self.rules: set = set()          # "flag", "coulomb": how the frames' statuses were found
        self.ids = self.radius = self.fixed = None
        self.prev: tuple | None = None   # (step, time, theta, where) of the previous frame

    # -- the frame --------------------------------------------------------------------------
    def convert(self, raw: RawFrame) -> Frame:
        where = label(self.k, raw.step, raw.where)
        u = self.units
        step = int(raw.step)
        time = float(raw.time) / u.time if raw.time is not None else math.nan
        theta = float(raw.theta_deg)
        if not math.isfinite(theta):
            raise InputError(f"{where}: theta_deg is {theta} (not a finite number)")
        if not 0.0 <= theta <= 90.0:
            raise InputError(f"{where}: theta_deg = {theta!r} is outside [0, 90]: the analysis "
                             "follows a ramp tilting towards +x (mirror x if yours tilts the other "
                             "way)")
        if raw.time is not None and not math.isnan(float(raw.time)) and not math.isfinite(time):
            raise InputError(f"{where}: time is {raw.time} (not a finite number)")
        if self.prev is not None:
            p_step, p_time, p_theta, p_where = self.prev
            if step <= p_step:
                raise InputError(f"{where}: frames out of order: step {step} follows step "
                                 f"{p_step} ({p_where})")
            if time < p_time:
                raise InputError(f"{where}: frames out of order: time {time!r} follows time "
                                 f"{p_time!r} ({p_where})")
            if theta < p_theta - BACKWARDS_DEG:
                raise InputError(f"{where}: theta_deg goes backwards, {theta!r} after {p_theta!r} "
                                 f"({p_where}): import one ramp, its angle never decreasing")
        index, position, radius, fixed, velocity, omega, rotation = self._grains(raw, where)
        pair, force, status, overlap = self._contacts(raw, where, index, position, radius)
        ke = math.nan
        if velocity is not None and omega is not None:  # as the DEM engine computes it
            m = np.where(fixed, 0.0, np.pi * radius**2)
            ke = float(0.5 * np.sum(m * (velocity[:, 0] ** 2 + velocity[:, 1] ** 2
                                         + 0.5 * radius**2 * omega**2)))
        n = radius.size
        nan_n = np.full(n, math.nan)
        frame = Frame(index=self.k, step=step, time=time, theta_deg=theta, position=position,
                      rotation=nan_n if rotation is None else rotation,
                      velocity=np.full((n, 2), math.nan) if velocity is None else velocity,
                      omega=nan_n.copy() if omega is None else omega, iterations=0, residual=0.0,
                      pair=pair, force=force, status=status, ke=ke, max_overlap=overlap,
                      max_iterations=0, cap_hits=0, missed=0, energy_gain=math.nan)
        last_time = self.prev[1] if self.prev is not None else -math.inf   # the last time given
        self.prev = (step, time if not math.isnan(time) else last_time, theta, raw.where)
        self.k += 1
        return frame

    # -- grains -----------------------------------------------------------------------------
    def _grains(self, raw: RawFrame, where: str):
        u = self.units
        ids = integers(raw.id, "id", where)
        n = ids.size
        if ids.ndim != 1 or n == 0:
            raise InputError(f"{where}: no grains")
        if (ids < 0).any():
            raise InputError(f"{where}: grain id {int(ids[ids < 0][0])} is negative (negative ids "
                             "are the walls: -1 floor, -2 left, -3 right)")
        order = np.argsort(ids, kind="stable")
        ids = ids[order]
        dup = ids[1:] == ids[:-1]
        if dup.any():
            raise InputError(f"{where}: grain id {int(ids[1:][dup][0])} appears twice")
        for field, a, shape in (("position", raw.position, (n, 2)), ("radius", raw.radius, (n,)),
                                ("fixed", raw.fixed, (n,)), ("velocity", raw.velocity, (n, 2)),
                                ("omega", raw.omega, (n,)), ("rotation", raw.rotation, (n,))):
            if a is not None and np.shape(a) != shape:
                raise InputError(f"{where}: {field} has shape {np.shape(a)}, expected {shape} "
                                 f"({n} grains)")
        pos = finite(raw.position, "position", where, raw.id, columns=("x", "y"))[order] / u.length
        radius = finite(raw.radius, "radius", where, raw.id)[order] / u.length
        fixed = flags(raw.fixed, "fixed", where)[order]
        vel = None if raw.velocity is None else \
            finite(raw.velocity, "velocity", where, raw.id, columns=("vx", "vy"))[order] * (u.time / u.length)
        omega = None if raw.omega is None else finite(raw.omega, "omega", where, raw.id)[order] * u.time
        rot = None if raw.rotation is None else finite(raw.rotation, "rotation", where, raw.id)[order]
        if (radius <= 0).any():
            k = int(np.flatnonzero(radius <= 0)[0])
            raise InputError(f"{where}: radius of grain id {int(ids[k])} is {float(radius[k])!r} (must be > 0)")
        if self.ids is None:
            self._first_grains(ids, radius, fixed, where)
        else:
            self._same_grains(ids, radius, fixed, where)
        L = self.box_length
        out = (pos[:, 0] < 0.0) | (pos[:, 0] > L) | (pos[:, 1] < 0.0)
        if out.any():
            k = int(np.flatnonzero(out)[0])
            raise InputError(
                f"{where}: x, y of grain id {int(ids[k])}, ({pos[k, 0]:.6g}, {pos[k, 1]:.6g}) d, "
                f"is outside the box 0 <= x <= L = {L:.6g} d, y >= 0: give positions with the "
                "floor at y = 0 and the side walls at x = 0 and x = L (and --length-unit)")
        return ids, pos, radius, fixed, vel, omega, rot

    def _first_grains(self, ids, radius, fixed, where) -> None:
        mobile = ~fixed
        if not mobile.any():
            raise InputError(f"{where}: every grain is fixed: nothing to analyse")
        mean = float(2.0 * radius[mobile].mean())
        lo, hi = MEAN_DIAMETER
        if not lo <= mean <= hi:
            raise InputError(f"{where}: the mobile grains' mean diameter is {mean:.6g} d: lengths "
                             f"must be in units of the mean diameter d (give --length-unit "
                             f"{mean * self.units.length:.6g}, the mean diameter in your units)")
        self.ids, self.radius, self.fixed = ids, radius, fixed

    def _same_grains(self, ids, radius, fixed, where) -> None:
        if ids.size != self.ids.size or not np.array_equal(ids, self.ids):
            missing = np.setdiff1d(self.ids, ids)
            extra = np.setdiff1d(ids, self.ids)
            what = (f"grain id {int(missing[0])} of frame 0 is missing" if missing.size
                    else f"grain id {int(extra[0])} is not in frame 0")
            raise InputError(f"{where}: {what} (every frame holds the same grains)")
        for field, a, b in (("radius", radius, self.radius), ("fixed", fixed, self.fixed)):
            if not np.array_equal(a, b):
                k = int(np.flatnonzero(a != b)[0])
                raise InputError(f"{where}: {field} of grain id {int(ids[k])} is {a[k].item()!r}, "
                                 f"{b[k].item()!r} in frame 0 (a grain keeps its {field})")

    # -- contacts ---------------------------------------------------------------------------
    def _contacts(self, raw: RawFrame, where: str, ids, position, radius):
        u = self.units
        c = np.shape(raw.id1)[0] if np.ndim(raw.id1) else -1
        for field, a in (("id1", raw.id1), ("id2", raw.id2), ("fn", raw.fn), ("ft", raw.ft),
                         ("sliding", raw.sliding)):
            if a is not None and np.shape(a) != (max(c, 0),):
                raise InputError(f"{where}: contact field {field} has shape {np.shape(a)}, "
                                 f"expected ({max(c, 0)},) like id1")
        a = integers(raw.id1, "contact id1", where)
        b = integers(raw.id2, "contact id2", where)
        fn = finite(raw.fn, "contact fn", where, what="contact") / u.force
        ft = finite(raw.ft, "contact ft", where, what="contact") / u.force
        wall_first = (a < 0) & (b >= 0)
        a, b = np.where(wall_first, b, a), np.where(wall_first, a, b)
        bad = (a < 0) | (b < -3)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise InputError(f"{where}: contact row {k} joins ids {int(a[k])} and {int(b[k])}: a "
                             "contact joins a grain to a grain or to a wall (-1 floor, -2 left, "
                             "-3 right)")
        same = a == b
        if same.any():
            raise InputError(f"{where}: contact row {int(np.flatnonzero(same)[0])} joins grain id "
                             f"{int(a[same][0])} to itself")
        i = np.searchsorted(ids, a)
        j_grain = b >= 0
        j = np.searchsorted(ids, np.where(j_grain, b, ids[0]))
        for side, idx, want in (("id1", i, a), ("id2", j, np.where(j_grain, b, ids[0]))):
            idx = np.minimum(idx, ids.size - 1)
            unknown = ids[idx] != want
            if unknown.any():
                raise InputError(f"{where}: contact {side} {int(want[unknown][0])} is no grain of "
                                 f"the frame (row {int(np.flatnonzero(unknown)[0])})")
        j = np.where(j_grain, j, b)
        swap = j_grain & (j < i)
        i, j = np.where(swap, j, i), np.where(swap, i, j)   # f_n, f_t do not change (Newton)
        n = ids.size
        order = contact_order(i, j, n)
        i, j, fn, ft = i[order], j[order], fn[order], ft[order]
        key = i * (n + 3) + np.where(j >= 0, j, n - 1 - j)
        dup = key[1:] == key[:-1]
        if dup.any():
            k = int(np.flatnonzero(dup)[0]) + 1
            other = f"grain id {int(ids[j[k]])}" if j[k] >= 0 else f"wall {int(j[k])}"
            raise InputError(f"{where}: the contact of grain id {int(ids[i[k]])} and {other} is "
                             "listed twice")
        mu = np.where(j < 0, self.mu_wall, self.mu)
        if raw.sliding is not None:
            sliding = flags(raw.sliding, "contact sliding", where)[order]
            self.rules.add("flag")
        elif self.eps is None:
            raise InputError(f"{where}: the source flags no sliding contacts: give --eps for the "
                             "Coulomb test")
        else:
            sliding = np.abs(ft) >= mu * fn * (1.0 - self.eps)
            self.rules.add("coulomb")
        status = np.where(fn > 0.0, np.where(sliding, 2, 1), 0).astype(np.int8)
        pair = np.column_stack([i, j]).astype(np.int32)
        overlap = _overlaps(i, j, position, radius, self.box_length)
        return (pair, np.column_stack([fn, ft]), status,
                float(overlap.max()) if overlap.size else 0.0)


def _overlaps(i, j, position, radius, box_length) -> np.ndarray:
    """Each contact's overlap [d]: r_i + r_j - |x_i - x_j|, or r_i less the distance to the wall."""
    g = j >= 0
    jj = np.where(g, j, 0)
    d = position[i] - position[jj]
    out = radius[i] + radius[jj] - np.hypot(d[:, 0], d[:, 1])
    x, y, r = position[i, 0], position[i, 1], radius[i]
    out = np.where(j == -1, r - y, out)
    out = np.where(j == -2, r - x, out)
    return np.where(j == -3, x + r - box_length, out)
