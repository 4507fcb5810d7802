"""What a run file holds: every dataset (``LAYOUT``, with the frame and contact columns and their
dtypes) and attribute (``ATTRS``), the filters every dataset carries, and the root attributes
that mark its integrity record. Declared here once; the writer writes it, the reader checks it."""

from __future__ import annotations

import numpy as np

FRAME_SCALARS = {"step": np.int64, "time": np.float64, "theta_deg": np.float64,
                 "iterations": np.int64, "residual": np.float64, "ke": np.float64,
                 "max_overlap": np.float64, "max_iterations": np.int64, "cap_hits": np.int64,
                 "missed": np.int64, "energy_gain": np.float64}
FRAME_ARRAYS = ("position", "velocity", "rotation", "omega")  # per grain, float64
CONTACT_SETS = {"pair": (np.int32, (2,)), "force": (np.float64, (2,)), "status": (np.int8, ())}

# every dataset of a run file: (units, one-line description); written as its attrs
LAYOUT = {
    "particles/radius": ("d", "grain radius"),
    "particles/fixed": ("1", "true for the grains of the rough bottom row (they never move)"),
    "frames/step": ("1", "global step of the frame (deposition steps included)"),
    "frames/time": ("sqrt(d/g)", "simulated time of the frame"),
    "frames/theta_deg": ("deg", "inclination of the box"),
    "frames/position": ("d", "grain centres (x along the floor, y up), box frame"),
    "frames/rotation": ("rad", "grain rotation angle"),
    "frames/velocity": ("sqrt(g d)", "grain velocity, box frame"),
    "frames/omega": ("sqrt(g/d)", "grain angular velocity"),
    "frames/iterations": ("1", "NLGS sweeps of the frame's step"),
    "frames/residual": ("1", "final NLGS residual of the frame's step (relative change of the impulses)"),
    "frames/ke": ("m g d", "kinetic energy of the mobile grains"),
    "frames/max_overlap": ("d", "largest overlap since the previous frame"),
    "frames/max_iterations": ("1", "most NLGS sweeps in a step since the previous frame"),
    "frames/cap_hits": ("1", "steps since the previous frame that hit solver.max_iter"),
    "frames/missed": ("1", "steps since the previous frame where a grain outran the alert distance"),
    "frames/energy_gain": ("m g d", "largest per-step gain of kinetic energy beyond the work of "
                                    "gravity since the previous frame (<= 0 up to solver error)"),
    "contacts/offset": ("1", "contacts of frame k are rows offset[k]:offset[k+1]"),
    "contacts/pair": ("1", "grain ids (i < j); walls: -1 floor, -2 left (x = 0), -3 right (x = L)"),
    "contacts/force": ("m g", "normal, tangential contact force (impulse / dt)"),
    "contacts/status": ("1", "0 open (touching, no force), 1 sticking, 2 sliding (|f_t| = mu f_n)"),
}
# The attributes of the root and of the groups that hold only attributes, each with its meaning
# (docs/run-file.md); /preparation only with protocol.pretilt_deg (one entry per leg), /health
# only in complete runs, its keys those of tiltpile.health.summarize (None here).
ATTRS = {
    "/": {
        "tiltpile_version": "version of tiltpile that wrote the file",
        "seed": "the run's seed",
        "config": "the validated configuration (JSON text)",
        "config_hash": "SHA-256 of the configuration's canonical JSON",
        "box_length": "box length L [d]",
        "jit": "the numba flags the kernels were compiled with (JSON text)",
        "complete": "true once the run is finished",
        "integrity": '"fletcher32": every dataset carries HDF5\'s Fletcher32 checksum',
        "attrs_sha256": "SHA-256 over the attributes of the root and the groups (verify checks it)",
        "end_reason": '"theta_max" (the ramp reached theta_max_deg) or "slide" (protocol.end_ke)',
        "end_theta_deg": "tilt of the last frame [deg]",
        "steps": "time steps of the whole run, deposition and preparation included",
        "sweeps": "NLGS sweeps of the whole run",
        "capped_steps": "steps of the whole run that stopped at solver.max_iter",
        "seconds": "wall time of the invocation that finished the run [s]",
        "resumed_from_frame": "the frame that invocation resumed from; -1: not resumed",
        "wall_seconds": "wall time of the run summed over its invocations, each interrupted one "
                        "up to its last checkpoint [s]",
        "wall_seconds_whole": "true when every invocation was counted (false: the run was "
                              "resumed from a checkpoint written before this sum existed)",
    },
    "deposition": {
        "steps": "deposition steps",
        "time": "simulated time of the deposition [sqrt(d/g)]",
        "ke_per_grain": "kinetic energy per mobile grain at its end [m g d]",
        "height": "highest grain top [d]",
        "max_overlap": "largest overlap of any deposition step [d]",
        "missed": "deposition steps where a grain outran the alert distance",
    },
    "preparation": {
        "target_deg": "the leg's target tilt [deg]",
        "tilt_steps": "steps tilting to it",
        "hold_steps": "steps held there until at rest",
        "ke_per_grain": "kinetic energy per mobile grain at the leg's end [m g d]",
    },
    "health": None,
}
# datasets that files written before they existed lack (the reader fills energy_gain with NaN)
OPTIONAL = frozenset({"frames/energy_gain"})
INTEGRITY = "fletcher32"  # root attr ``integrity`` of files whose every dataset is checksummed
# HDF5 filters of every dataset: the checksum (compression measured, not adopted: docs/performance.md)
FILTERS = {"fletcher32": True}
# A writer stops with "no space left on device" while this much space (plus twice what one
# checkpoint interval writes) is still free: HDF5 cannot close a file whose writes failed (h5py
# then crashes the process), so the run stops while its file can still be closed whole.
RESERVE_BYTES = 4 << 20

ATTRS_DIGEST = "attrs_sha256"  # root attr of complete files: SHA-256 over every attribute
