"""The paper presets are frozen: their configuration and the first steps of their runs, bit for bit.

The paper-scale ensemble is computed over many sessions; every run of it must simulate the same
thing. A change of the `paper` preset, of the solver or of the protocol that alters its numbers
must come behind an option that is off (or as a new preset), never silently. This test pins

* the paper preset's configuration hash (any edit of presets/paper.toml, or of a default it
  relies on, changes it), and
* the state after the first 600 deposition steps of seed 0 (three chunks of 200: grains falling
  onto the rough bottom, the NLGS already at ~600 sweeps per step in the third chunk), as a
  SHA-256 over positions, rotations, velocities, contact impulses and states, and the sweep count.

``paper-fast`` (the paper preset with its history's legs at 10x the ramp's rate, computed over
sessions too) is pinned by its configuration hash, by being ``paper`` but for that rate (so the
deposition prefix above holds for it), and by the first frames of its protocol on a 60-grain pile
(deposition, the whole +-16 deg history at its rate, 6 frames of the ramp).

About 10 s on one core. The digests hold on this machine's numba/LLVM (fastmath off, sim/jit.py);
on another CPU or numba version they may legitimately differ: then regenerate them here, from a
commit whose paper runs are known to be unchanged, and say so in the commit message.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

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


# -- paper-fast: the paper preset with its history's legs at 10x the ramp's rate ----------------

PAPER_FAST_HASH = "643332a7b7ebbc02a2129f2afda3477a55727905d68eeadeadacc86c6010997c"
# the paper-fast preset on a 60-grain pile (box 8 d), up to 0.25 deg of its ramp: deposition, the
# whole +-16 deg history at 0.01 deg per step and the first 6 frames (~2 s once compiled)
SMALL_FAST = ("scene.n=60", "scene.box_length=8.0", "protocol.theta_max_deg=0.25")
SMALL_FAST_DIGEST = "3cfb53c2587f673566f7664922d1f2f579460b69ae9e815f274fc61fde1f493e"
SMALL_FAST_SWEEPS = 1266249


@pytest.mark.parametrize("name, factor", [("paper-fast", 10), ("paper-5x", 5)])
def test_the_faster_histories_are_the_paper_preset_but_for_the_historys_rate(name, factor):
    """paper-fast (10x) and paper-5x, the next rate issue 53 checks, differ from paper in the
    history's rate only: their deposition (pinned above by the paper prefix), solver, ramp and
    frames are the paper's."""
    paper, fast = config.load("paper"), config.load(name)
    if name == "paper-fast":
        assert fast.hash() == PAPER_FAST_HASH
    for section in ("scene", "solver", "health"):
        assert getattr(fast, section) == getattr(paper, section)
    differ = {f for f in type(paper.protocol).__dataclass_fields__
              if getattr(paper.protocol, f) != getattr(fast.protocol, f)}
    assert differ == {"pretilt_per_step_deg"}
    assert fast.protocol.pretilt_per_step_deg == factor * paper.protocol.tilt_per_step_deg


def test_paper_fast_first_frames_are_bit_identical():
    cfg = config.load("paper-fast", overrides=list(SMALL_FAST))
    frames, legs, end = [], None, None
    for ev in protocol.run(cfg, 0):
        if isinstance(ev, protocol.Frame):
            frames.append(ev)
        elif isinstance(ev, protocol.Prepared):
            legs = ev.legs
        elif isinstance(ev, protocol.Ended):
            end = ev
    # the history ran at 0.01 deg per step: 1600 steps to +16 deg, 3200 for each leg of 32 deg
    assert [leg["tilt_steps"] for leg in legs] == [1600, 3200, 3200, 3200, 3200, 1600]
    assert [f.index for f in frames] == list(range(6)) and end.reason == "theta_max"
    h = hashlib.sha256()
    for f in frames:
        for k in ("position", "rotation", "velocity", "omega", "pair", "force", "status"):
            a = np.ascontiguousarray(getattr(f, k))
            h.update(k.encode() + str(a.dtype).encode() + str(a.shape).encode() + a.tobytes())
    assert (h.hexdigest(), end.sweeps) == (SMALL_FAST_DIGEST, SMALL_FAST_SWEEPS)
