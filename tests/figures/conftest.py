"""The figure tests' session ensemble: three smoke piles, shared by the notebook tests and the
record tests (built once per session, only by the tests that ask for it)."""

from __future__ import annotations

import pytest

SMOKE_SEEDS = [1, 2, 3]


@pytest.fixture(scope="session")
def smoke_ensemble(tmp_path_factory):
    """Three smoke runs and their observables, as `make figures PRESET=smoke RUNS=3` makes them."""
    from tiltpile import config
    from tiltpile.analysis import compute_observables
    from tiltpile.ensemble import failed_runs, run_ensemble

    out = tmp_path_factory.mktemp("smoke_ensemble")
    manifest = run_ensemble(config.load("smoke"), SMOKE_SEEDS, out, workers=2, progress=False)
    assert failed_runs(manifest) == []
    compute_observables(out, workers=2, progress=False)
    return out
