"""bench.coarse: the energy-norm projections on rigid blocks and block stresses, and the study."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tiltpile.bench import coarse, settle
from tiltpile.sim import protocol
from tiltpile.sim.solver import IMPULSE, nlgs

CAP = 40  # the tiny run's solver.max_iter (conftest.TINY_CAP)


@pytest.fixture
def prepared(tiny_state):
    """A system at frame 20's angle with its next step prepared (free velocities, contacts)."""
    cfg, seed, theta, st = tiny_state
    s = protocol.make_system(cfg, seed)
    s.restore(st)
    settle.prepare_step(s, theta, cfg.protocol.tilt_per_step_deg)
    return s


def _dense_projection(basis, e, w):
    """||P e||^2 by dense weighted least squares: basis (dof, k), e and w (dof,)."""
    sw = np.sqrt(w)
    x, *_ = np.linalg.lstsq(basis * sw[:, None], e * sw, rcond=None)
    r = sw * (e - basis @ x)
    return float(np.sum(w * e * e) - r @ r)


def test_g_is_the_velocity_change_the_sweeps_make(prepared):
    s = prepared
    p = s.params
    c, vel = s.c.copy(), s.vel.copy()
    nlgs(s.ci, s.cj, c, s.status.copy(), vel, 0.0, 30, p["mode"], s.rng.copy(),
         np.empty(s.ci.shape[0], np.int64), 1.0, False)
    g = coarse.impulse_to_velocity(s.ci, s.cj, s.c, s.vel)
    dp = (c[:, IMPULSE] - s.c[:, IMPULSE]).reshape(-1)
    dv = (vel - s.vel)[:, :3].reshape(-1)
    assert np.abs(dv).max() > 0
    np.testing.assert_allclose(g @ dp, dv, rtol=0, atol=1e-12 * np.abs(dv).max())


def _rigid_basis(s, block):
    """The block-rigid subspace written out as dense columns (translation x, y, rotation about the
    block's centre of mass) over the velocity components of the bodies."""
    n = s.n
    w = coarse.energy_weights(s.vel, n)
    mob = w[:n, 0] > 0
    cells = np.floor(s.pos[:n] / block).astype(int)
    keys = sorted({tuple(k) for k in cells[mob]})
    cols = []
    for key in keys:
        sel = mob & np.all(cells == key, axis=1)
        m = w[:n, 0][sel]
        ctr = (m[:, None] * s.pos[:n][sel]).sum(0) / m.sum()
        for kind in range(3):
            col = np.zeros((s.vel.shape[0], 3))
            if kind < 2:
                col[:n][sel, kind] = 1.0
            else:
                d = s.pos[:n][sel] - ctr
                col[:n][sel, 0] = -d[:, 1]
                col[:n][sel, 1] = d[:, 0]
                col[:n][sel, 2] = s.radius[sel]
            cols.append(col.reshape(-1))
    return np.array(cols).T, w


@pytest.mark.parametrize("block", [2.0, 3.5])
def test_rigid_projection_is_the_least_squares_one(prepared, block):
    s = prepared
    basis, w = _rigid_basis(s, block)
    rng = np.random.default_rng(4)
    e = rng.normal(size=(s.vel.shape[0], 3))
    got = coarse.rigid_captured(e, w, s.pos, s.radius, block)
    assert got == pytest.approx(_dense_projection(basis, e.reshape(-1), w.reshape(-1)), rel=1e-10)
    # a field in the subspace is captured whole, one outside it only in part
    inside = (basis @ rng.normal(size=basis.shape[1])).reshape(-1, 3)
    assert coarse.rigid_captured(inside, w, s.pos, s.radius, block) == pytest.approx(
        coarse.norm2(inside, w), rel=1e-10)
    assert got < 0.9 * coarse.norm2(e, w)


@pytest.mark.parametrize("gradient", [False, True])
def test_stress_projection_is_the_least_squares_one(prepared, gradient):
    s = prepared
    w = coarse.energy_weights(s.vel, s.n)
    g = coarse.impulse_to_velocity(s.ci, s.cj, s.c, s.vel)
    q = coarse.stress_basis(s.ci, s.c, s.pos, s.radius, 3.0, gradient)
    proj = coarse.Projector(g, q, w)
    rng = np.random.default_rng(5)
    e = rng.normal(size=(s.vel.shape[0], 3)) * (w > 0)
    dense = (g @ q).toarray()
    assert proj.captured(e) == pytest.approx(_dense_projection(dense, e.reshape(-1), w.reshape(-1)),
                                             rel=1e-6)
    inside = (g @ (q @ rng.normal(size=q.shape[1]))).reshape(-1, 3)
    assert proj.captured(inside) == pytest.approx(coarse.norm2(inside, w), rel=1e-6)


def test_stress_basis_is_n_sigma_n_and_t_sigma_n(prepared):
    s = prepared
    q = coarse.stress_basis(s.ci, s.c, s.pos, s.radius, 100.0, False).toarray()
    assert q.shape[1] == 3  # one block
    sigma = np.array([[1.3, -0.4], [-0.4, 0.7]])
    p = q @ np.array([1.3, 0.7, -0.4])
    for a in range(s.ci.shape[0]):
        nrm = s.c[a, :2]
        t = np.array([-nrm[1], nrm[0]])
        assert p[2 * a] == pytest.approx(nrm @ sigma @ nrm)
        assert p[2 * a + 1] == pytest.approx(t @ sigma @ nrm)
    assert coarse.stress_basis(s.ci, s.c, s.pos, s.radius, 100.0, True).shape[1] == 9


def test_correlation_of_a_uniform_and_of_a_random_field():
    rng = np.random.default_rng(6)
    n = 3000
    pos = rng.uniform(0, 60, size=(n, 2))
    w = np.ones((n + 3, 3))
    w[n:] = 0
    uniform = np.tile([0.3, -0.2, 0.0], (n + 3, 1))
    assert coarse.correlation(uniform, w, pos) == pytest.approx([1.0] * len(coarse.CORR_AT))
    noise = rng.normal(size=(n + 3, 3))
    assert np.all(np.abs(coarse.correlation(noise, w, pos)) < 0.05)


def test_the_pile_goes_on_as_the_run_does(tiny_state):
    """The measured steps leave the pile where the run's own steps do, bit for bit."""
    cfg, seed, theta, st = tiny_state
    dth = cfg.protocol.tilt_per_step_deg
    a, b = protocol.make_system(cfg, seed), protocol.make_system(cfg, seed)
    a.restore(st)
    b.restore(st)
    capped = 0
    for k in range(6):
        rec = a.advance(1, theta + k * dth, dth)
        settle.prepare_step(b, theta + k * dth, dth)
        out = coarse.measure_step(b, [10, CAP], 300, [3.0])
        settle.finish_step(b)
        assert out["sweeps"] == rec.iterations[0]
        capped += out["sweeps"] == CAP
        if out["sweeps"] < 10:  # stopped on tol before the first cap: nothing to measure
            assert out["error"] == {}
        for name in ("pos", "rot", "vel", "c", "status", "rng"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), (k, name)
    assert capped


def test_study_chart_and_errors(tiny_run, tmp_path, capsys):
    js, png = tmp_path / "c.json", tmp_path / "c.png"
    coarse.main([str(tiny_run), "--frames", "20", "--steps", "3", "--caps", "10", "--long", "300",
                 "--blocks", "5", "3", "--warm", "1", "--json", str(js), "--chart", str(png),
                 "--quiet"])
    res = json.loads(js.read_text())
    row = res["rows"][0]
    assert row["caps"] == [10, CAP] and res["blocks"] == [5, 3] and len(row["steps"]) == 3
    for k, c in row["summary"]["caps"].items():
        assert 0 < c["error"] and all(0 <= f <= 1 + 1e-9 for sp in c["captured"].values() for f in sp)
    assert png.stat().st_size > 0 and "frame   20" in capsys.readouterr().out
    coarse.main(["--plot", str(js), "--chart", str(tmp_path / "again.png")])
    for argv, msg in (([str(tiny_run), "--frames", "9999"], "frame 9999 out of range"),
                      ([str(tmp_path / "none.h5"), "--frames", "1"], "none.h5"),
                      (["--plot", str(js)], "--plot needs --chart"),
                      ([str(tiny_run), "--frames", "1", "--blocks", "0"], "--blocks > 0"),
                      ([str(tiny_run)], "give a run file and --frames")):
        with pytest.raises(SystemExit, match="bench.coarse: error: .*" + msg.replace("-", r"\-")):
            coarse.main(argv)


def test_interface_basis_selects_the_contacts_between_blocks(prepared):
    s = prepared
    n = s.n
    one_block = coarse.interface_basis(s.ci, s.cj, s.pos, 1e3)
    walls = np.nonzero(s.cj >= n)[0]
    assert walls.size and one_block.shape[1] == 2 * walls.size
    assert set(one_block.nonzero()[0] // 2) == set(walls)
    assert coarse.interface_basis(s.ci, s.cj, s.pos, 1e-3).shape[1] == 2 * s.ci.shape[0]


def test_feasible_projects_on_the_cones():
    p = np.array([[1.0, 0.2], [1.0, -0.9], [-0.5, 0.1], [2.0, 1.5]])
    mu = np.full(4, 0.5)
    np.testing.assert_array_equal(coarse.feasible(p, mu),
                                  [[1.0, 0.2], [1.0, -0.5], [0.0, 0.0], [2.0, 1.0]])


def test_an_oracle_over_every_contact_finishes_the_solve_and_stays(tiny_state):
    """With every contact in the subspace the oracle's correction is the long solve's answer
    (up to the ridge), applied consistently to impulses and velocities: the sweeps after it then
    stay there. The pile goes on as the run does."""
    cfg, seed, theta, st = tiny_state
    dth = cfg.protocol.tilt_per_step_deg
    a, b = protocol.make_system(cfg, seed), protocol.make_system(cfg, seed)
    a.restore(st)
    b.restore(st)
    rec = a.advance(1, theta, dth)
    settle.prepare_step(b, theta, dth)
    out = coarse.oracle_step(b, 5, CAP, 2000, [1e-3, 3.0], ridge=1e-12)
    settle.finish_step(b)
    assert out["sweeps"] == rec.iterations[0] == CAP
    for name in ("pos", "rot", "vel", "c", "status", "rng"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    plain, full = np.array(out["errors"]["plain"]), np.array(out["errors"]["interface/0.001"])
    assert out["dims"]["interface/0.001"] == out["unknowns"] and out["dims"]["plain"] == 0
    assert max(out["drift"].values()) < 1e-9
    assert plain.min() > 1e-3 and full.max() < 1e-4 * plain.min()
    assert set(out["errors"]) == {"plain", "stress/0.001", "stress/3", "stress_grad/0.001",
                                  "stress_grad/3", "interface/0.001", "interface/3", "rigid/0.001",
                                  "rigid/3"}
    # rigid blocks of one grain each: the velocity error itself is in the subspace, and the
    # impulses over every contact realise it
    assert out["dims"]["rigid/0.001"] == 3 * int((b.vel[: b.n, 3] > 0).sum())
    assert np.max(out["errors"]["rigid/0.001"]) < 1e-3 * plain.min()


def test_summarize_oracle_reach():
    steps = [dict(sweeps=30, points=[10, 20, 30], dims={"plain": 0, "x": 4}, unknowns=8,
                  errors={"plain": [0.5, 0.4, 0.3], "x": [0.35, 0.3, 0.1]}),
             dict(sweeps=12, points=[10, 20, 30], dims={"plain": 0, "x": 4}, unknowns=8,
                  errors={"plain": [0.1, 0.1, 0.1], "x": [0.1, 0.1, 0.1]})]
    m = coarse.summarize_oracle(steps, 30)
    assert m["capped"] == 1 and m["variants"]["plain"]["reach_plain_cap"] == 30
    assert m["variants"]["x"]["reach_plain_cap"] == 20 and m["variants"]["x"]["dim_fraction"] == 0.5


def test_oracle_study_chart_and_errors(tiny_run, tmp_path, capsys):
    js = tmp_path / "o.json"
    coarse.main([str(tiny_run), "--frames", "20", "--steps", "2", "--oracle", "10", "--long", "300",
                 "--blocks", "3", "--warm", "1", "--json", str(js), "--chart", str(tmp_path / "o.png"),
                 "--quiet"])
    res = json.loads(js.read_text())
    assert res["kind"] == "oracle" and res["ridge"] == coarse.ORACLE_RIDGE
    assert "interface/3" in capsys.readouterr().out
    coarse.main(["--plot", str(js), "--chart", str(tmp_path / "again.png")])
    other = tmp_path / "b.json"
    other.write_text(json.dumps(dict(res, kind=None)))
    for argv, msg in ((["--plot", str(js), str(other), "--chart", str(tmp_path / "x.png")], "one kind"),
                      ([str(tiny_run), "--frames", "1", "--oracle", "0"], "--oracle must be"),
                      ([str(tiny_run), "--frames", "1", "--oracle", "5", "--ridge", "0"], "--ridge must be")):
        with pytest.raises(SystemExit, match="bench.coarse: error: .*" + msg.replace("-", r"\-")):
            coarse.main(argv)
