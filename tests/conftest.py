"""Shared fixtures: one settled smoke pile per session (see simhelpers for hand-built cases)."""

from __future__ import annotations

import pytest

from tiltpile import config
from tiltpile.sim import protocol
from simhelpers import CALIBRATED


@pytest.fixture(scope="session")
def smoke_config():
    """The smoke preset with the sweep the pile-specific tests were measured with (CALIBRATED)."""
    return config.load("smoke", None, list(CALIBRATED))


@pytest.fixture(scope="session")
def settled_pile(smoke_config):
    """A deposited smoke pile (System) at theta = 0, computed once per session."""
    return protocol.deposited(smoke_config, seed=3)
