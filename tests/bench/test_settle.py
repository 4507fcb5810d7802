"""bench.settle: NLGS in chunks is the production solve, and LMGC90's velocity norms."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from simhelpers import make_system

from tiltpile.bench import settle
from tiltpile.sim import protocol
from tiltpile.sim.solver import IMPULSE, SWEEPS, natural_residual, nlgs

CAP = 40  # the tiny run's solver.max_iter (conftest.TINY_CAP)


@pytest.fixture
def run_file(tiny_run):
    return tiny_run


@pytest.fixture
def state(tiny_state):
    return tiny_state


def _system(state):
    cfg, seed, _, st = state
    s = protocol.make_system(cfg, seed)
    s.restore(st)
    return s


def test_a_measured_step_is_the_runs_step_bit_for_bit(state):
    cfg, _, theta, _ = state
    dth = cfg.protocol.tilt_per_step_deg
    a, b = _system(state), _system(state)
    a.ref[:] = np.inf  # the first step rebuilds the contact list
    b.ref[:] = np.inf
    points = settle.log_points(10, CAP, 300)
    for k in range(15):
        rec = a.advance(1, theta + k * dth, dth)
        settle.prepare_step(b, theta + k * dth, dth)
        step = settle.solve_step(b, points, settle.LMGC_TOL)
        settle.finish_step(b)
        assert step["sweeps"] == rec.iterations[0] and step["chunk_equal"]
        for name in ("pos", "rot", "vel", "c", "key", "status", "ref", "rng"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), (k, name)


@pytest.mark.parametrize("sweep", ["interleaved", "forward"])
def test_chunks_of_sweeps_are_one_call(state, sweep):
    """k calls of m sweeps continue the iteration of one call of k m sweeps, pruned sweeps and
    all (tol 0: no call stops early)."""
    cfg, _, theta, _ = state
    s = _system(state)
    s.params.update(mode=SWEEPS[sweep])
    settle.prepare_step(s, theta, cfg.protocol.tilt_per_step_deg)
    p = s.params
    one_c, one_v, one_st = s.c.copy(), s.vel.copy(), s.status.copy()
    perm = np.empty(s.ci.shape[0], np.int64)
    it, _, _ = nlgs(s.ci, s.cj, one_c, one_st, one_v, 0.0, 250, p["mode"], s.rng.copy(), perm, 1.0, True)
    assert it == 250
    c, v, st = s.c.copy(), s.vel.copy(), s.status.copy()
    for _ in range(10):
        it, _, _ = nlgs(s.ci, s.cj, c, st, v, 0.0, 25, p["mode"], s.rng.copy(), perm, 1.0, True)
        assert it == 25
    assert np.array_equal(c, one_c) and np.array_equal(v, one_v) and np.array_equal(st, one_st)


def test_one_disk_landing_gives_the_norms_by_hand():
    """One disk falling onto the floor, before any sweep: R = 0 and the local solution R' stops
    it, so dV = -W R', and QuadDV = sqrt 2 / tol, QuadDVR = 1 / tol, MeanDVoR = -1 / tol; after
    one sweep the contact is solved exactly and every norm is 0 (up to rounding)."""
    s = make_system([0.5], [[50.0, 0.5]])
    settle.prepare_step(s, 0.0, 0.0)
    assert s.ci.shape[0] == 1
    tol = 1e-3
    sums = settle.check_pass(s.ci, s.cj, s.c, s.vel)
    assert sums[5] == 1.0
    qdv, qdvr, mdvor = settle.lmgc_norms(sums, tol)
    assert qdv == pytest.approx(math.sqrt(2) / tol) and qdvr == pytest.approx(1 / tol)
    assert mdvor == pytest.approx(-1 / tol)
    perm = np.empty(1, np.int64)
    nlgs(s.ci, s.cj, s.c, s.status, s.vel, 0.0, 1, 0, s.rng, perm, 1.0, False)
    after = settle.lmgc_norms(settle.check_pass(s.ci, s.cj, s.c, s.vel), tol)
    assert after == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)  # rounding of the exact solve


def test_norms_are_zero_without_load_or_change_and_the_natural_residual_is_the_solvers(state):
    cfg, _, theta, _ = state
    assert settle.lmgc_norms(np.zeros(8), 1e-4) == (0.0, 0.0, 0.0)
    s = _system(state)
    settle.prepare_step(s, theta, cfg.protocol.tilt_per_step_deg)
    for _ in range(3):
        sums = settle.check_pass(s.ci, s.cj, s.c, s.vel)
        nat = natural_residual(s.ci, s.cj, s.c, s.vel)
        assert settle.natural_from(sums) == pytest.approx(nat, rel=1e-12)
        assert all(np.isfinite(settle.lmgc_norms(sums, 1e-4)))
        u = settle.local_velocities(s.ci, s.cj, s.c, s.vel)
        same = settle.increment_sums(s.c, u, s.c[:, IMPULSE].copy(), u)
        assert settle.lmgc_norms(same, 1e-4) == (0.0, 0.0, 0.0)
        perm = np.empty(s.ci.shape[0], np.int64)
        nlgs(s.ci, s.cj, s.c, s.status, s.vel, 0.0, 20, s.params["mode"], s.rng, perm, 1.0, True)


def test_the_study_logs_every_step_and_draws_its_chart(run_file, tmp_path):
    out, png = tmp_path / "s.json", tmp_path / "s.png"
    res = settle.main([str(run_file), "--frames", "20", "25", "--steps", "4", "--every", "10",
                       "--long", "300", "--warm", "1", "--json", str(out), "--chart", str(png),
                       "--quiet"])
    assert res["sweeps"] == [10, 20, 30, 40, 140, 240, 300]
    for row in res["rows"]:
        assert all(row["chunk_equal"]) and len(row["step_sweeps"]) == 4
        for name in settle.SERIES:
            x = np.array(row["series"][name])
            assert x.shape == (4, 7) and np.isfinite(x).all(), name
        # the reference is the end of the long solve: no error there
        assert np.all(np.array(row["series"]["disp_err_mean"])[:, -1] == 0.0)
        assert 0.0 <= row["summary"]["capped"] <= 1.0
    assert json.loads(out.read_text())["rows"][1]["frame"] == 25
    assert png.stat().st_size > 0
    again = tmp_path / "again.png"
    settle.main(["--plot", str(out), str(out), "--chart", str(again)])
    assert again.stat().st_size > 0


@pytest.mark.parametrize("argv, words", [
    (["nowhere.h5", "--frames", "1"], "no run file"),
    (["RUN", "--frames", "10000"], "frame 10000 out of range"),
    (["RUN", "--frames", "-1"], "frame -1 out of range"),
    (["RUN"], "--frames"),
    (["RUN", "--frames", "1", "--every", "0"], "--every"),
    (["--plot", "x.json"], "--chart"),
    (["--plot", "missing.json", "--chart", "x.png"], "cannot read missing.json"),
])
def test_bad_input_is_refused_in_one_line(run_file, argv, words):
    argv = [str(run_file) if a == "RUN" else a for a in argv]
    with pytest.raises(SystemExit) as e:
        settle.main(argv)
    msg = str(e.value)
    assert words in msg and "\n" not in msg
