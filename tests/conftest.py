"""Shared fixtures: one settled smoke pile per session (see simhelpers for hand-built cases)."""

from __future__ import annotations

import pytest

from tiltpile import config
from tiltpile.sim import protocol


@pytest.fixture(scope="session")
def smoke_config():
    return config.load("smoke")


@pytest.fixture(scope="session")
def settled_pile(smoke_config):
    """A deposited smoke pile (System) at theta = 0, computed once per session."""
    sysm = None
    gen = protocol.run(smoke_config, seed=3)
    for ev in gen:
        if isinstance(ev, protocol.Checkpoint) and ev.state["scalars"]["phase"] == "tilt":
            sysm = protocol.make_system(smoke_config, 3)
            sysm.restore(ev.state)
            break
    gen.close()
    assert sysm is not None
    return sysm
