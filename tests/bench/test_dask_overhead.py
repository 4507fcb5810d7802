"""``python -m tiltpile.bench.dask_overhead``: the CPU dask spends beside a busy task."""

from __future__ import annotations

import pytest

from tiltpile.bench import dask_overhead


def test_the_housekeeping_is_measured_beside_a_busy_task():
    """One busy task of 0.5 s of thread CPU per setting: the worker's CPU covers it (what is
    beyond it is the housekeeping, not the task) and the wall time does too. How much each
    setting costs is the benchmark's answer, not asserted here (a timed test on a shared machine);
    that the quiet setting reaches the workers is tests/workflow/test_ensemble.py's."""
    d = dask_overhead.measure("default", 0.5)
    q = dask_overhead.measure("quiet", 0.5)
    for r in (d, q):
        assert r["worker_extra_cpu_s"] > -0.05 and r["client_cpu_s"] >= 0.0, r
        assert r["wall_s"] >= 0.5 and r["overhead_per_task_s"] > -0.1, r
    assert (d["setting"], q["setting"]) == ("default", "quiet")


def test_bad_input_is_one_line():
    with pytest.raises(SystemExit):
        dask_overhead.main(["--seconds", "0"])
