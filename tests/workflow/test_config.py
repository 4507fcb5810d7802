"""Configuration: presets load, bad input fails with the field name and the allowed range."""

import pytest

from tiltpile import config
from tiltpile.config import ConfigError


@pytest.mark.parametrize("name", config.PRESETS)
def test_presets_load(name):
    cfg = config.load(name)
    assert cfg.scene.mu == 0.5
    assert len(cfg.hash()) == 64


def test_paper_preset_matches_the_paper():
    cfg = config.load("paper")
    assert cfg.scene.n == 4000 and cfg.scene.box_length == 120.0
    assert cfg.protocol.tilt_per_step_deg == 0.001 and cfg.protocol.frame_every == 50
    assert cfg.protocol.theta_max_deg == 30.0 and cfg.scene.polydispersity == 0.2
    # Deboeuf et al.'s history: to 16 deg, two full cycles +-16 deg, back to 0, at the ramp's rate
    assert cfg.protocol.pretilt_deg == (16.0, -16.0, 16.0, -16.0, 16.0, 0.0)
    assert cfg.protocol.pretilt_per_step_deg == 0.0
    assert cfg.protocol.history_step_deg == 0.001 and cfg.protocol.history_rate == 1.0


def test_paper_fresh_is_the_paper_preset_without_its_history():
    """presets/paper-fresh.toml starts from paper.toml (``base``) and drops the history only: every
    other value is the paper preset's, and its hash is that of the fresh paper runs."""
    import dataclasses
    paper, fresh = config.load("paper"), config.load("paper-fresh")
    assert fresh.protocol.pretilt_deg == ()
    assert dataclasses.replace(paper, protocol=dataclasses.replace(paper.protocol, pretilt_deg=())) == fresh
    assert fresh.hash().startswith("a2a1ff442489")  # the fresh paper runs measured so far


@pytest.mark.parametrize("override, words", [
    ("scene.mu=-0.1", ["scene.mu", "[0.0, inf)"]),
    ("scene.n=0", ["scene.n", "[1,"]),
    ("scene.polydispersity=1.0", ["scene.polydispersity", "[0.0, 1.0)"]),
    ("solver.dt=0", ["solver.dt", "(0.0"]),
    ("solver.dt=-1", ["solver.dt"]),
    ("scene.n=2.5", ["scene.n", "integer"]),
    ("scene.n=true", ["scene.n", "integer"]),
    ("solver.sweep=sideways", ["solver.sweep", "forward"]),
    ("solver.tol='small'", ["solver.tol", "number"]),
    ("scene.colour=1", ["unknown key scene.colour"]),
    ("physics.g=1", ["unknown section"]),
    ("dt=1", ["section.key"]),
])
def test_bad_values_name_the_field_and_range(override, words):
    with pytest.raises(ConfigError) as e:
        config.load("smoke", overrides=[override])
    for w in words:
        assert w in str(e.value)


def test_override_and_file(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text("[solver]\ndt = 0.005\n")
    cfg = config.load("smoke", f, ["solver.tol=1e-3"])
    assert cfg.solver.dt == 0.005 and cfg.solver.tol == 1e-3
    assert cfg.hash() != config.load("smoke").hash()
    assert config.from_json(cfg.to_json()) == cfg


def test_config_is_frozen():
    cfg = config.load("smoke")
    with pytest.raises(Exception):
        cfg.scene.mu = 1.0


def test_broken_toml(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text("[solver\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        config.load("smoke", f)
    with pytest.raises(ConfigError, match="not found"):
        config.load("smoke", tmp_path / "missing.toml")


@pytest.mark.parametrize("name", config.PRESETS)
def test_config_toml_reads_back_to_the_same_configuration_over_any_preset(name, tmp_path):
    """The TOML config_toml writes of every key of a configuration reads back to the same values
    and, given as --config over any preset of its engine, is that configuration (its hash),
    history included, fresh or cycled. (A file cannot take a DEM preset's optional [dem] section
    away: over default-dem, a Contact Dynamics configuration stays a DEM one.)"""
    cfg = config.load(name)
    f = tmp_path / "again.toml"
    f.write_text(config.config_toml(cfg.to_dict()))
    assert config.read_toml(f) == {k: {key: list(v) if isinstance(v, tuple) else v
                                       for key, v in sec.items()} for k, sec in cfg.to_dict().items()}
    bases = [b for b in config.PRESETS if cfg.engine == "lammps" or config.load(b).engine == "cd"]
    assert len(bases) >= 6
    assert {base: config.load(base, f).hash() for base in bases} == dict.fromkeys(bases, cfg.hash())


def test_config_toml_writes_numpy_scalars_as_their_values_and_leaves_none_out():
    import numpy as np

    text = config.config_toml({"b": {"x": np.float32(0.1), "n": np.int64(3), "on": np.bool_(True),
                                     "inf": -np.inf, "gone": None}, "a": {"s": np.str_("cd")}})
    assert text == ('[a]\ns = "cd"\n\n[b]\n# gone: unset\ninf = -inf\nn = 3\non = true\n'
                    f"x = {float(np.float32(0.1))!r}\n")
    with pytest.raises(TypeError, match="no TOML form for dict"):
        config.config_toml({"a": {"t": {"nested": 1}}})


def test_cli_reference_lists_every_configuration_key():
    """docs/cli.md's "Configuration keys" paragraph names every field of every section."""
    import dataclasses
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "cli.md").read_text()
    assert set(config.SECTIONS) == {"scene", "solver", "protocol", "health", "dem"}
    for section, cls in config.SECTIONS.items():
        listed = re.search(rf"`{section}\.\{{([^}}]*)\}}`", text)
        assert listed, f"docs/cli.md lists no {section} keys"
        names = {n.strip() for n in listed.group(1).split(",")}
        assert names == {f.name for f in dataclasses.fields(cls)}, section


def test_a_history_given_later_replaces_the_presets_in_either_form(tmp_path):
    """Later layers win, whichever form of the history they use: legs written out replace the
    preset's shorthand (a run file's TOML with pretilt_deg = [] is fresh on any preset), and a
    shorthand replaces legs given before it; both forms in one layer are refused."""
    f = tmp_path / "c.toml"
    f.write_text("[protocol]\npretilt_deg = []\n")
    assert config.load("paper", f).hash() == config.load("paper-fresh").hash()
    assert config.load("paper", overrides=["protocol.pretilt_deg=[5.0,0.0]"]).protocol.pretilt_deg == (5.0, 0.0)
    f.write_text("[protocol]\npretilt_deg = [5.0, 0.0]\n")
    cfg = config.load("default", f, ["protocol.cycles=1", "protocol.theta_rev_deg=3.0"])
    assert cfg.protocol.pretilt_deg == (3.0, -3.0, 3.0, 0.0)
    f.write_text("[protocol]\npretilt_deg = [5.0, 0.0]\ncycles = 1\ntheta_rev_deg = 3.0\n")
    with pytest.raises(ConfigError, match="both give a history"):
        config.load("default", f)


# -- the preset on the command line -----------------------------------------------------------------

@pytest.mark.parametrize("command, extra", [("simulate", ["--seed", "1", "--out", "run.h5"]),
                                            ("ensemble", ["--runs", "2", "--out", "runs"])])
def test_commands_that_make_runs_require_a_preset(command, extra, tmp_path, monkeypatch, capsys):
    """No silent default scale: without --preset the command stops (exit 2) naming it, before
    anything is written; --help says it is required and what each preset is."""
    from tiltpile.cli import build_parser, main

    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        main([command, *extra])
    assert e.value.code == 2
    assert "the following arguments are required: --preset" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    helptext = " ".join(build_parser()._subparsers._group_actions[0].choices[command]
                        .format_help().split())
    assert "(required)" in helptext and "paper 4000 grains" in helptext


def test_bench_says_which_preset_it_measures(monkeypatch, capsys):
    """The step timing (python -m benchmarks.timing) keeps its measurement default (paper-fresh),
    shows it in --help and prints the preset on stderr before measuring, saying whether it is
    the default; --set reaches the configuration."""
    import benchmarks.timing as timing

    seen = []
    monkeypatch.setattr(timing, "time_pile", lambda **kw: seen.append(kw) or {"preset": kw["preset"]})
    assert timing.main(["--json"]) == 0
    out, err = capsys.readouterr()
    assert err.splitlines()[0] == "python -m benchmarks.timing: preset paper-fresh (the default; --preset to choose)"
    assert seen[-1]["preset"] == "paper-fresh" and '"preset": "paper-fresh"' in out
    assert timing.main(["--json", "--preset", "smoke", "--set", "solver.tol=1e-5"]) == 0
    assert capsys.readouterr().err.splitlines()[0] == "python -m benchmarks.timing: preset smoke"
    assert seen[-1]["preset"] == "smoke" and seen[-1]["overrides"] == ["solver.tol=1e-5"]
    with pytest.raises(SystemExit):
        timing.main(["--help"])
    assert "(default: paper-fresh)" in " ".join(capsys.readouterr().out.split())


def test_the_configuration_defaults_are_the_fresh_default_preset():
    """config.py's dataclass defaults are the default-fresh preset's values (a preset file gives
    only what it changes; every preset gives its scale explicitly), so a configuration built from
    nothing is that preset, hash and all: a run file's TOML, which leaves out an empty history,
    reads back as the run it was."""
    assert config.from_dict({}) == config.load("default-fresh")
    assert config.from_dict({}).hash() == config.load("default-fresh").hash()


def test_the_default_preset_is_default_fresh_with_deboeufs_history():
    """presets/default.toml cycles its piles as the paper preset does (to 16 deg, two full cycles
    +-16 deg, back to 0), its history's legs at 10x the ramp's rate (0.02 deg per step);
    default-fresh drops the history only, and its hash is that of the fresh default runs."""
    import dataclasses
    default, fresh = config.load("default"), config.load("default-fresh")
    assert default.protocol.pretilt_deg == (16.0, -16.0, 16.0, -16.0, 16.0, 0.0)
    assert default.protocol.pretilt_per_step_deg == 10 * default.protocol.tilt_per_step_deg == 0.02
    assert default.protocol.history_step_deg == 0.02 and default.protocol.history_rate == 10.0
    assert fresh.protocol.pretilt_deg == ()
    assert dataclasses.replace(default, protocol=dataclasses.replace(
        default.protocol, pretilt_deg=(), pretilt_per_step_deg=0.0)) == fresh
    assert default.hash().startswith("f822c0f99af7")  # the committed default figures' runs
    assert fresh.hash().startswith("fa89eabe2003")    # figures/default-fresh's runs


def test_a_dem_stiffness_whose_collision_spans_too_few_steps_is_refused():
    """4 k_n at the default DEM step: a collision of the two smallest grains would last ~27 steps,
    fewer than 30; with the step halved it lasts as many as at k_n (t_c ~ 1 / sqrt(k_n))."""
    import math

    base = config.load("default-dem")
    n0 = config.dem_contact_steps(base)
    assert n0 >= config.DEM_MIN_CONTACT_STEPS
    with pytest.raises(config.ConfigError, match=r"dem.dt = 8e-05 is too long for dem.kn = 800000.0"):
        config.load("default-dem", None, [f"dem.kn={4 * base.dem.kn}"])
    stiff = config.load("default-dem", None, [f"dem.kn={4 * base.dem.kn}", f"dem.dt={base.dem.dt / 2}"])
    assert math.isclose(config.dem_contact_steps(stiff), n0)
    # the formula: the damped oscillator's half period (e = 1: pi sqrt(m_eff / k))
    undamped = config.load("default-dem", None, ["dem.restitution=1.0"])
    d = 1 - undamped.scene.polydispersity
    assert math.isclose(config.dem_contact_time(undamped),
                        math.pi * math.sqrt(math.pi * d * d / 8 / undamped.dem.kn))
