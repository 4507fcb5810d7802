"""Protocol options: a preparation history before the analysed ramp (``protocol.pretilt_deg``) and
the end-of-run rule (``protocol.end_ke``, ``end_span_deg``)."""

from __future__ import annotations

import numpy as np
import pytest

from tiltpile import config
from tiltpile.cli import main
from tiltpile.runner import simulate
from tiltpile.sim import protocol
from tiltpile.store import open_run

TINY = ["scene.n=60", "scene.box_length=10.0", "protocol.checkpoint_every=3"]
# legs of 1000, 2000 and 1000 steps at the smoke rate (0.01 deg per step): a checkpoint falls
# inside the second leg (every 10 chunks of 200 steps, and at the end of each leg)
PRETILT = TINY + ["protocol.theta_max_deg=1.0", "protocol.pretilt_deg=[10.0, -10.0, 0.0]"]
SLIDE = TINY + ["protocol.theta_max_deg=40.0", "protocol.end_ke=1e-4", "protocol.end_span_deg=0.5"]


def _events(cfg, seed, state=None, stop=None):
    """All events of a run (from ``state``), stopping after the first checkpoint ``stop`` accepts."""
    out = []
    for ev in protocol.run(cfg, seed, state):
        out.append(ev)
        if isinstance(ev, protocol.Checkpoint) and stop is not None and stop(ev.state["scalars"]):
            break
    return out


def _of(events, kind):
    return [e for e in events if isinstance(e, kind)]


@pytest.fixture(scope="module")
def pretilted():
    cfg = config.load("smoke", overrides=PRETILT)
    return cfg, _events(cfg, 2)


def test_pretilt_legs_run_in_order_and_end_at_rest(pretilted):
    cfg, events = pretilted
    (prep,) = _of(events, protocol.Prepared)
    assert [leg["target_deg"] for leg in prep.legs] == [10.0, -10.0, 0.0]
    assert [leg["tilt_steps"] for leg in prep.legs] == [1000, 2000, 1000]  # at the ramp's 0.01 deg/step
    assert all(leg["ke_per_grain"] < cfg.protocol.rest_ke for leg in prep.legs)
    assert all(leg["hold_steps"] >= cfg.protocol.rest_steps for leg in prep.legs)
    # the gravity angle goes up to 10, down to -10 and back to 0, in that order
    angles = np.array([e.theta_deg for e in _of(events, protocol.Progress) if e.phase == "pretilt"])
    i_max, i_min = int(np.argmax(angles)), int(np.argmin(angles))
    assert angles[i_max] == pytest.approx(10.0) and angles[i_min] == pytest.approx(-10.0)
    assert i_max < i_min and angles[-1] == pytest.approx(0.0, abs=1e-12)
    # the analysed ramp starts at 0 deg after the history, and the pile was tilted before it
    order = [type(e).__name__ for e in events if not isinstance(e, (protocol.Progress, protocol.Checkpoint))]
    assert order[:3] == ["Deposited", "Prepared", "Frame"]
    frames = _of(events, protocol.Frame)
    assert frames[0].theta_deg == 0.0 and frames[-1].theta_deg == pytest.approx(1.0)
    assert len(frames) == protocol.n_frames(cfg.protocol)
    fresh = _of(_events(config.load("smoke", overrides=PRETILT[:-1]), 2), protocol.Frame)
    assert not np.array_equal(fresh[0].position, frames[0].position)


def test_pretilt_killed_during_a_leg_resumes_bit_identically(pretilted):
    cfg, full = pretilted
    head = _events(cfg, 2, stop=lambda sc: sc["phase"] == "pretilt" and sc["leg"] == 1 and sc["leg_step"] > 0)
    state = _of(head, protocol.Checkpoint)[-1].state
    assert state["scalars"]["phase"] == "pretilt" and 0 < state["scalars"]["leg_step"]
    tail = _events(cfg, 2, state=state)
    assert _of(tail, protocol.Prepared)[0].legs == _of(full, protocol.Prepared)[0].legs
    a, b = _of(full, protocol.Frame), _of(tail, protocol.Frame)
    assert len(a) == len(b)
    for fa, fb in zip(a, b):
        for name in ("position", "velocity", "omega", "rotation", "pair", "force", "status"):
            np.testing.assert_array_equal(getattr(fa, name), getattr(fb, name))


def test_pretilt_history_is_recorded_in_the_run_file(tmp_path):
    cfg = config.load("smoke", overrides=PRETILT)
    summary = simulate(cfg, 2, tmp_path / "r.h5", progress=False)
    with open_run(tmp_path / "r.h5") as run:
        np.testing.assert_array_equal(run.preparation["target_deg"], [10.0, -10.0, 0.0])
        np.testing.assert_array_equal(run.preparation["tilt_steps"], [1000, 2000, 1000])
        assert run.theta_deg[0] == 0.0 and run.end_reason == "theta_max"
        # the run's cost: every step counted, deposition and preparation included
        prep = int(run.preparation["tilt_steps"].sum() + run.preparation["hold_steps"].sum())
        tilt = round(cfg.protocol.theta_max_deg / cfg.protocol.tilt_per_step_deg)
        steps = run.deposition["steps"] + prep + cfg.protocol.rest_steps + tilt
        assert run.cost["steps"] == summary["steps"] == steps == int(run.step[-1])
        assert run.cost["sweeps"] == summary["sweeps"] >= steps
        assert 0 <= run.cost["capped_steps"] == summary["capped_steps"] <= steps


@pytest.mark.parametrize("value, field", [("[95.0, 0.0]", "protocol.pretilt_deg[0]"),
                                          ("[nan, 0.0]", "protocol.pretilt_deg[0]"),
                                          ("15.0", "protocol.pretilt_deg"),
                                          ('"15, 0"', "protocol.pretilt_deg"),
                                          ("[10.0, true]", "protocol.pretilt_deg[1]"),
                                          ("[10.0]", "protocol.pretilt_deg")])
def test_bad_history_is_refused_naming_the_field_and_nothing_is_written(tmp_path, capsys, value, field):
    out = tmp_path / "x.h5"
    assert main(["simulate", "--preset", "smoke", "--seed", "1", "--quiet", "--out", str(out),
                 "--set", f"protocol.pretilt_deg={value}"]) == 2
    err = capsys.readouterr().err
    assert field in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("sets, field", [
    (["protocol.cycles=2"], "protocol.theta_rev_deg"),
    (["protocol.theta_rev_deg=16.0"], "protocol.cycles"),
    (["protocol.cycles=-1", "protocol.theta_rev_deg=16.0"], "protocol.cycles"),
    (["protocol.cycles=1.5", "protocol.theta_rev_deg=16.0"], "protocol.cycles"),
    (["protocol.cycles=2", "protocol.theta_rev_deg=95.0"], "protocol.theta_rev_deg"),
    (["protocol.cycles=2", "protocol.theta_rev_deg=nan"], "protocol.theta_rev_deg"),
    (["protocol.pretilt_per_step_deg=0.02"], "protocol.pretilt_per_step_deg"),
    (["protocol.cycles=2", "protocol.theta_rev_deg=16.0", "protocol.pretilt_per_step_deg=-1.0"],
     "protocol.pretilt_per_step_deg"),
])
def test_bad_shorthand_or_history_rate_is_refused_in_one_line(tmp_path, capsys, sets, field):
    out = tmp_path / "x.h5"
    args = ["simulate", "--preset", "smoke", "--seed", "1", "--quiet", "--out", str(out)]
    assert main(args + [a for s in sets for a in ("--set", s)]) == 2
    err = capsys.readouterr().err
    assert field in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_later_keys_keep_old_hashes():
    """Configurations that do not use the keys added later hash as before them."""
    base = config.load("default-fresh")
    assert "pretilt_deg" not in base.to_json() and "end_ke" not in base.to_json()
    assert base.hash().startswith("fa89eabe2003")  # figures/default-fresh's config hash
    used = config.load("default-fresh", overrides=["protocol.end_ke=1e-3"])
    assert used.hash() != base.hash() and config.from_json(used.to_json()) == used


@pytest.fixture(scope="module")
def slid():
    cfg = config.load("smoke", overrides=SLIDE)
    return cfg, _events(cfg, 1)


def test_run_ends_once_the_slide_has_lasted_end_span(slid):
    cfg, events = slid
    frames = _of(events, protocol.Frame)
    (end,) = _of(events, protocol.Ended)
    n_mob = int((~protocol.make_system(cfg, 1).fixed).sum())
    above = np.array([f.ke / n_mob > cfg.protocol.end_ke for f in frames])
    span = round(cfg.protocol.end_span_deg / (cfg.protocol.frame_every * cfg.protocol.tilt_per_step_deg))
    assert end.reason == "slide" and end.frames == len(frames) < protocol.n_frames(cfg.protocol)
    assert end.theta_deg == pytest.approx(frames[-1].theta_deg)
    assert above[-span:].all(), "the last end_span_deg of frames are not all above end_ke"
    runs = np.convolve(above[:-1].astype(int), np.ones(span, int), "valid")
    assert (runs < span).all(), "an earlier stretch of frames already satisfied the rule"


def test_a_run_killed_after_its_last_checkpoint_still_reports_how_it_ended(slid):
    cfg, events = slid
    last = _of(events, protocol.Checkpoint)[-1].state
    assert last["scalars"]["phase"] == "done"
    tail = _events(cfg, 1, state=last)
    assert _of(tail, protocol.Ended) == _of(events, protocol.Ended) and not _of(tail, protocol.Frame)


def test_without_the_rule_the_ramp_goes_to_theta_max(pretilted):
    cfg, events = pretilted
    (end,) = _of(events, protocol.Ended)
    assert end.reason == "theta_max" and end.theta_deg == pytest.approx(cfg.protocol.theta_max_deg)


def test_slide_cap_applies_only_after_a_frame_above_slide_cap_ke():
    """solver.max_iter_slide caps the steps that follow a frame whose kinetic energy per grain
    exceeds solver.slide_cap_ke; the frames before the first such frame are those of the plain run."""
    over = TINY + ["protocol.theta_max_deg=30.0", "solver.max_iter=1000", "solver.slide_cap_ke=1e-4"]
    plain = _of(_events(config.load("smoke", overrides=over), 1), protocol.Frame)
    cfg = config.load("smoke", overrides=over + ["solver.max_iter_slide=50"])
    capped = _of(_events(cfg, 1), protocol.Frame)
    n_mob = int((~protocol.make_system(cfg, 1).fixed).sum())
    fast = [f.ke / n_mob > 1e-4 for f in plain]
    first = fast.index(True)
    for a, b in zip(plain[: first + 1], capped[: first + 1]):
        np.testing.assert_array_equal(a.position, b.position)
    assert max(f.max_iterations for f in plain[first + 1:]) > 50, "the plain run never needed more"
    sliding = [f.ke / n_mob > 1e-4 for f in capped]
    after = [f for prev, f in zip(sliding, capped[1:]) if prev]
    assert after and all(f.max_iterations <= 50 for f in after)
    before = [f for prev, f in zip(sliding, capped[1:]) if not prev]
    assert any(f.max_iterations > 50 for f in before)


def test_history_rate_of_its_own_leaves_the_ramp_alone():
    """protocol.pretilt_per_step_deg tilts the history legs at their own rate: 5x the ramp's
    rate makes each leg 5x shorter, and the analysed ramp keeps its frames and rate."""
    cfg = config.load("smoke", overrides=PRETILT + ["protocol.pretilt_per_step_deg=0.05"])
    events = _events(cfg, 2)
    (prep,) = _of(events, protocol.Prepared)
    assert [leg["tilt_steps"] for leg in prep.legs] == [200, 400, 200]
    assert all(leg["ke_per_grain"] < cfg.protocol.rest_ke for leg in prep.legs)
    frames = _of(events, protocol.Frame)
    assert len(frames) == protocol.n_frames(cfg.protocol)
    assert np.diff([f.theta_deg for f in frames]) == pytest.approx(
        cfg.protocol.frame_every * cfg.protocol.tilt_per_step_deg)


def test_deboeuf_shorthand_is_the_same_run_as_its_legs():
    legs = config.load("smoke", overrides=TINY + ["protocol.pretilt_deg=[4.0,-4.0,4.0,0.0]"])
    short = config.load("smoke", overrides=TINY + ["protocol.cycles=1", "protocol.theta_rev_deg=4"])
    assert short.protocol.pretilt_deg == (4.0, -4.0, 4.0, 0.0)
    assert short.hash() == legs.hash() and short == legs
