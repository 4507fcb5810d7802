"""The paper preset is frozen: its configuration and the first steps of its run, bit for bit.

The paper-scale ensemble is computed over many sessions; every run of it must simulate the same
thing. A change of the `paper` preset, of the solver or of the protocol that alters its numbers
must come behind an option that is off (or as a new preset), never silently. This test pins

* the paper preset's configuration hash (any edit of presets/paper.toml, or of a default it
  relies on, changes it), and
* the state after the first 600 deposition steps of seed 0 (three chunks of 200: grains falling
  onto the rough bottom, the NLGS already at ~600 sweeps per step in the third chunk), as a
  SHA-256 over positions, rotations, velocities, contact impulses and states, and the sweep count.

About 10 s on one core. The digests hold on this machine's numba/LLVM (fastmath off, sim/jit.py);
on another CPU or numba version they may legitimately differ: then regenerate them here, from a
commit whose paper runs are known to be unchanged, and say so in the commit message.
"""

from __future__ import annotations

import hashlib

import numpy as np

from tiltpile import config
from tiltpile.sim import protocol

PAPER_HASH = "c22bab2311c253f67c59980e57c69b21f88d4641f43fc6483d0ad3446febec45"
PREFIX_STEPS = 600
PREFIX_DIGEST = "d9d2f3bcb083e73a726c22f2ab84adb4c4e3a81fd521ea8987ea74aac725f1c7"
PREFIX_SWEEPS = 154742


def _prefix_state(cfg, seed: int, steps: int):
    """The simulator's state after the first ``steps`` steps of ``protocol.run`` (whole chunks)."""
    gen = protocol.run(cfg, seed)
    try:
        for ev in gen:
            if isinstance(ev, protocol.Progress) and ev.step >= steps:
                # the generator's own System, exactly as the run holds it at this point
                return gen.gi_frame.f_locals["sysm"].state()
    finally:
        gen.close()
    raise AssertionError("the run ended before the prefix")


def _digest(state: dict) -> str:
    h = hashlib.sha256()
    for k in ("pos", "rot", "vel", "c", "status"):
        a = np.ascontiguousarray(state[k])
        h.update(k.encode())
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def test_paper_preset_configuration_is_pinned():
    assert config.load("paper").hash() == PAPER_HASH


def test_paper_run_prefix_is_bit_identical():
    state = _prefix_state(config.load("paper"), 0, PREFIX_STEPS)
    assert state["scalars"]["step"] == PREFIX_STEPS
    assert (_digest(state), state["scalars"]["sweeps"]) == (PREFIX_DIGEST, PREFIX_SWEEPS)
