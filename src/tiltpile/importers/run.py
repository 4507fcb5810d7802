"""Checked frames into a run file of the usual layout (docs/import.md, "What the run file holds").

``import_run(reader, out, ...)`` reads every frame once to check it all (nothing is written
before the last frame has passed), keeping the converted frames in memory up to
``BUFFER_BYTES`` (past that it reads them again to write them), then writes the run file with
the store's own writer (``store.RunWriter``, the simulator's and the DEM's) under a temporary
name beside ``out`` (``outputs.replaced_whole``): the file appears whole under its name, or
not at all, and an older ``out`` (``force``) is replaced only then. The configuration it
records is derived from the data and the options (``derived_config``); the source, the
contact-status rule and the units go to the attrs of ``/import``.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

import tiltpile
from tiltpile import config as cfgmod
from tiltpile.importers.frame import DEFAULT_EPS, Converter, InputError, Units
from tiltpile.outputs import replaced_whole
from tiltpile.sim.protocol import Ended
from tiltpile.store import RunWriteError, RunWriter, _describe_os_error, part_path, writer_lock

BUFFER_BYTES = 256 << 20   # converted frames kept between the check and the write
SET_BY_IMPORT = {("scene", "n"): "the data (its mobile grains)", ("scene", "box_length"): "--box-length",
                 ("scene", "mu"): "--mu", ("scene", "mu_wall"): "--mu-wall"}


def _sig(x: float, digits: int = 9) -> float:
    return float(f"{x:.{digits}g}")


def derived_config(n_mobile: int, radius_mobile: np.ndarray, box_length: float, mu: float,
                   mu_wall: float, theta: np.ndarray, overrides=()) -> cfgmod.Config:
    """The configuration an imported run records (docs/import.md): the scene from the data and
    the options (n, box_length, mu, mu_wall; polydispersity max |2 r - 1| of the mobile grains,
    below 1), the protocol from the angles (theta_max_deg the last frame's, the mean tilt
    between frames as tilt_per_step_deg with frame_every 1, or frame_every k steps of at most
    1 deg); the defaults elsewhere; ``overrides`` ("section.key=value", as --set) on top, but
    not on the keys the import sets (``SET_BY_IMPORT``)."""
    for text in overrides:
        layer = cfgmod.parse_override(text)
        for section, keys in layer.items():
            for key in keys:
                if (section, key) in SET_BY_IMPORT:
                    raise InputError(f"--set {text}: {section}.{key} is set by "
                                     f"{SET_BY_IMPORT[section, key]}")
    poly = min(_sig(float(np.max(np.abs(2.0 * radius_mobile - 1.0)))), 0.99)
    proto = {"theta_max_deg": _sig(float(min(max(theta[-1], 0.0), 90.0)))}
    span = float(theta[-1] - theta[0])
    if theta.size > 1 and span > 0:
        per = span / (theta.size - 1)
        every = max(1, math.ceil(per - 1e-12))
        proto.update(tilt_per_step_deg=_sig(per / every), frame_every=every)
    data = {"scene": {"n": int(n_mobile), "box_length": float(box_length), "mu": float(mu),
                      "mu_wall": float(mu_wall), "polydispersity": poly},
            "protocol": proto}
    return cfgmod.load_over(data, None, list(overrides))


def seed_of(out: Path, seed: int | None) -> int:
    """The run's id: ``seed``, else the first number in the file's name (run_0007.h5: 7), else 0."""
    if seed is not None:
        return cfgmod.check_seed(seed)
    m = re.search(r"(\d+)", Path(out).stem)
    return int(m.group(1)) if m else 0


def _nbytes(frame) -> int:
    return sum(np.asarray(getattr(frame, k)).nbytes for k in
               ("position", "velocity", "rotation", "omega", "pair", "force", "status"))


def import_run(reader, out, *, box_length: float, mu: float, mu_wall: float | None = None,
               eps: float | None = DEFAULT_EPS, units: Units | None = None, seed: int | None = None,
               overrides=(), force: bool = False, buffer_bytes: int = BUFFER_BYTES) -> dict:
    """Import the frames of ``reader`` (an iterable of ``RawFrame``s that can be iterated twice:
    ``lammps.LammpsReader``, ``plain.NpzReader``, ``plain.CsvReader``) into run file ``out``
    (module docstring). ``eps``: the Coulomb test's tolerance where the source flags no sliding
    contacts. Returns a summary (dict). ``InputError`` (one line naming the field and the frame)
    for input that does not pass, with nothing written."""
    out = Path(out)
    if out.suffix != ".h5":
        raise InputError(f"--out {out}: run files end in .h5")
    if out.exists() and not force:
        raise InputError(f"--out {out} exists; pass --force to replace it")
    units = units or Units()
    for name, v in (("--box-length", box_length), ("--mu", mu), ("--mu-wall", mu_wall),
                    ("--length-unit", units.length), ("--time-unit", units.time),
                    ("--force-unit", units.force)):
        if v is not None and not (math.isfinite(v) and (v > 0 or (name.startswith("--mu") and v >= 0))):
            raise InputError(f"{name} must be a {'non-negative' if name.startswith('--mu') else 'positive'} "
                             f"number, got {v!r}")
    if eps is not None and not 0.0 <= eps < 1.0:
        raise InputError(f"--eps must be in [0, 1), got {eps!r}")
    mu_wall = mu if mu_wall is None else mu_wall
    seed = seed_of(out, seed)

    def converted():
        conv = Converter(box_length, mu, mu_wall, eps, units)
        for raw in reader:
            yield conv, conv.convert(raw)

    kept, size, theta, steps, n_contacts = [], 0, [], [], 0
    conv = None
    for conv, frame in converted():   # the check: every frame, before anything is written
        theta.append(frame.theta_deg)
        steps.append(frame.step)
        n_contacts += frame.pair.shape[0]
        if kept is not None:
            size += _nbytes(frame)
            if size <= buffer_bytes:
                kept.append(frame)
            else:
                kept = None
    if conv is None or conv.k == 0:
        raise InputError("no frames to import")
    theta = np.asarray(theta)
    fixed, radius = conv.fixed, conv.radius
    cfg = derived_config(int((~fixed).sum()), radius[~fixed], conv.box_length, mu, mu_wall, theta,
                         overrides)
    coulomb = f"Coulomb: |f_t| >= mu f_n (1 - eps), eps = {eps!r}"
    status_rule = {frozenset({"flag"}): "the source's sliding flag", frozenset({"coulomb"}): coulomb,
                   }.get(frozenset(conv.rules), f"the source's sliding flag where given, else {coulomb}")
    source = reader.describe()
    provenance = [("format", source["format"]), ("source", json.dumps(source)),
                  ("status_rule", status_rule), ("eps", float("nan") if eps is None else float(eps)),
                  ("length_unit", float(units.length)), ("time_unit", float(units.time)),
                  ("force_unit", float(units.force)),
                  ("tiltpile_version", tiltpile.__version__)]
    frames = kept if kept is not None else (f for _, f in converted())
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise RunWriteError(f"cannot write {out}: {_describe_os_error(e)}") from None
    with writer_lock(out):
        if out.exists() and not force:
            raise InputError(f"--out {out} exists; pass --force to replace it")
        with replaced_whole(out) as tmp:
            writer = RunWriter(tmp, config_json=cfg.to_json(), config_hash=cfg.hash(), seed=seed,
                               radius=radius, fixed=fixed, box_length=conv.box_length, jit={})
            try:
                for frame in frames:
                    writer.append(frame)
                writer._log_attrs("import", provenance)
                writer.write_end(Ended("theta_max", float(theta[-1]), int(theta.size),
                                       steps=int(steps[-1])))
                writer.finish()
            except BaseException:
                writer.close()
                part_path(tmp).unlink(missing_ok=True)
                raise
    return {"path": str(out), "seed": seed, "format": source["format"], "frames": int(theta.size),
            "grains": int(radius.size), "mobile": int((~fixed).sum()), "contacts": int(n_contacts),
            "theta_deg": [float(theta[0]), float(theta[-1])], "status_rule": status_rule,
            "config_hash": cfg.hash()}
