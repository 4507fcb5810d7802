"""The presets are three axes, declared once in ``tiltpile.config``: a scale, a history and an
engine (``PRESET_AXES``). Every triple is a preset; the named presets (``PRESET_TABLE``) are
aliases of theirs and load to the very configuration (and hash) they had as TOML files of their
own (``preset_configs.json``, captured from those files before the axes). The Makefile reads the
presets from the package (``python -m tiltpile.cli.presets``) and resolves SCALE/HISTORY/ENGINE
to a preset; the README and docs tables are generated from or checked against the same list."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from makehelpers import MAKE_ENV, make_dry
from tiltpile import config
from tiltpile.report import document, scales

ROOT = Path(__file__).resolve().parents[2]
MAKEFILE = (ROOT / "Makefile").read_text()
BEFORE = json.loads((Path(__file__).parent / "preset_configs.json").read_text())["presets"]


def _table_rows(path: Path, heading: str) -> list[list[str]]:
    """The cells of the rows of the first table after ``heading`` in ``path``."""
    text = path.read_text()
    rest = text[text.index(heading):].split("\n")
    rows = [r for r in rest[1:] if r.startswith("|")]
    start = rest.index(rows[0])
    body = []
    for r in rest[start:]:
        if not r.startswith("|"):
            break
        body.append([c.strip() for c in r.strip("|").split("|")])
    return body[2:]


# ------------------------------------------------------------------------------------------------
# the package


@pytest.mark.parametrize("name", sorted(BEFORE))
def test_every_named_preset_composes_to_its_configuration_of_before_the_axes(name):
    """The alias's triple, composed (scale file + history + engine), is the configuration the
    preset's own TOML file gave: the same values, the same hash (so the same runs and records),
    and the same runs, figures directory and place in the report."""
    want = BEFORE[name]
    p = config.preset_info(name)
    data = config.compose_preset(p.scale, p.history, p.engine)
    cfg = config.from_dict(data)
    assert json.loads(cfg.to_json()) == want["config"]
    assert cfg.hash() == want["hash"] == config.load(name).hash()
    assert (p.runs, p.figures, p.report) == (want["runs"], want["figures"], want["report"])
    assert config.preset_of_axes(p.scale, p.history, p.engine) == p


def test_the_named_presets_are_those_of_before_in_their_order():
    assert set(config.PRESETS) == set(BEFORE) and len(config.PRESETS) == 11
    assert config.PRESETS == tuple(p.name for p in config.PRESET_TABLE)
    assert config.ALL_PRESETS[:len(config.PRESET_TABLE)] == config.PRESET_TABLE


def test_every_triple_of_the_axes_is_one_preset_with_one_name():
    axes = config.PRESET_AXES
    assert axes == {"scale": ("smoke", "default", "paper"), "history": ("fresh", "10x", "5x", "1x"),
                    "engine": ("cd", "dem")}
    triples = [(p.scale, p.history, p.engine) for p in config.ALL_PRESETS]
    assert sorted(triples) == sorted((s, h, e) for s in axes["scale"] for h in axes["history"]
                                     for e in axes["engine"])
    names = config.ALL_PRESET_NAMES
    assert len(set(names)) == len(names) == 24 and set(config.PRESETS) <= set(names)
    hashes = {config.load(n).hash() for n in names}
    assert len(hashes) == 24                          # 24 different configurations
    for p in config.ALL_PRESETS:
        assert p.figures == ("figures" if p.name == "default" else f"figures/{p.name}")
        assert config.preset_info(p.name) == p
        if p.name not in config.PRESETS:             # the systematic name, the scale's runs
            assert p.name == config.systematic_name(p.scale, p.history, p.engine)
            assert p.report == "" and p.runs == {"smoke": 4, "default": 6, "paper": 2}[p.scale]
    # the rule names 9 of the 11 named presets as they were named; paper-fast is paper at 10x
    renamed = {p.name: config.systematic_name(p.scale, p.history, p.engine) for p in config.PRESET_TABLE
               if p.name != config.systematic_name(p.scale, p.history, p.engine)}
    assert renamed == {"paper-fast": "paper-10x", "paper-fast-dem": "paper-10x-dem"}


def test_the_axes_resolve_to_a_preset_with_their_defaults():
    of = config.preset_of_axes
    assert of().name == "default" and of("paper").name == "paper" and of("smoke").name == "smoke"
    assert of("paper", "5x", "dem").name == "paper-5x-dem" and of("paper", "10x").name == "paper-fast"
    assert of(history="fresh").name == "default-fresh" and of(engine="dem").name == "default-dem"
    assert of("smoke", "5x", "dem").name == "smoke-5x-dem" and of("paper", "fresh", "dem").name == "paper-fresh-dem"
    cfg = config.load("smoke-5x-dem")                # the history at 5x the smoke ramp, in the DEM
    assert cfg.protocol.pretilt_deg == config.deboeuf_history(2, 16.0) and cfg.dem == config.DemConfig()
    assert cfg.protocol.history_rate == pytest.approx(5.0) and cfg.scene.n == 250
    assert config.load("default-1x").protocol.pretilt_per_step_deg == 0.0     # 1x: the ramp's own
    assert config.load("default-1x").protocol.history_rate == 1.0
    fresh = config.load("paper-fresh-dem")
    assert fresh.protocol.pretilt_deg == () and fresh.engine == "lammps"
    assert config.tilt_steps(config.load("paper")) == {"history": 160_000, "ramp": 30_000}


@pytest.mark.parametrize("axes, words", [
    ({"scale": "huge"}, ["unknown scale 'huge'", "smoke, default, paper"]),
    ({"scale": "paper", "history": "3x"}, ["unknown history '3x'", "fresh, 10x, 5x, 1x"]),
    ({"engine": "lammps"}, ["unknown engine 'lammps'", "cd, dem"]),
])
def test_an_unknown_axis_value_is_one_line_naming_the_axis_values(axes, words):
    with pytest.raises(config.ConfigError) as e:
        config.preset_of_axes(**axes)
    assert "\n" not in str(e.value) and all(w in str(e.value) for w in words), str(e.value)
    with pytest.raises(config.ConfigError):
        config.compose_preset(axes.get("scale", "default"), axes.get("history", "fresh"),
                              axes.get("engine", "cd"))


def test_an_unknown_preset_is_one_line_naming_every_preset():
    for bad in ("nope", "paper-10x", None):
        with pytest.raises(config.ConfigError) as e:
            config.preset_info(bad)
        text = str(e.value)
        assert "unknown preset" in text and "\n" not in text
        assert all(n in text for n in config.ALL_PRESET_NAMES)
    with pytest.raises(config.ConfigError, match="unknown preset 'nope'"):
        config.load("nope")


def test_the_report_reads_its_scales_from_the_table():
    inreport = [p.name for p in config.PRESET_TABLE if p.report]
    assert [s for s, _ in scales.SCALES] == inreport
    assert list(document.COMPARED) == [p.name for p in config.PRESET_TABLE if p.report == "claims"]
    assert dict(scales.SCALES)["default"] == "" and dict(scales.SCALES)["paper"] == "paper"
    for what, a, b in document.CONTRASTS:     # a pair of presets of the table, of a known kind
        assert what in document.KINDS and {a, b} <= set(config.PRESETS)


# ------------------------------------------------------------------------------------------------
# the command line


def test_tiltpile_presets_lists_and_resolves_the_presets(capsys):
    from tiltpile.cli import main

    assert main(["presets"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines[1:]] == [r for r in _axes_order()]
    assert main(["presets", "--scale", "paper", "--history", "5x", "--engine", "dem", "--name"]) == 0
    assert capsys.readouterr().out == "paper-5x-dem\n"
    assert main(["presets", "--scale", "paper", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert len(rows) == 1 and rows[0]["name"] == "paper" and rows[0]["runs"] == 50 and rows[0]["alias"]
    assert rows[0]["sweeps"] is None or rows[0]["sweeps"] > 0
    assert main(["presets", "--make"]) == 0
    made = capsys.readouterr().out.split()
    assert made == [f"{p.name}:{p.runs}:{p.report}" for p in config.ALL_PRESETS]
    assert main(["presets", "--history", "3x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown history '3x'" in err[0], err


def _axes_order() -> list[str]:
    axes = config.PRESET_AXES
    return [config.preset_of_axes(s, h, e).name for s in axes["scale"] for e in axes["engine"]
            for h in axes["history"]]


def test_the_makefiles_reading_of_the_presets_needs_the_standard_library_alone():
    """make reads the presets before `make setup` has built the venv: the module it runs imports
    tiltpile.config and the standard library, nothing installed."""
    code = ("import sys, tiltpile.cli.presets as m; sys.argv = ['x', '--make']; m.main(); "
            "print(sorted({n.split('.')[0] for n in sys.modules} & {'numpy', 'numba', 'h5py', 'jinja2', 'scipy'}))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       env={**MAKE_ENV, "PYTHONPATH": str(ROOT / "src")})
    assert r.returncode == 0 and r.stdout.splitlines()[-1] == "[]", r.stdout + r.stderr


def test_the_commands_answer_an_unknown_preset_with_the_presets(capsys):
    from tiltpile.cli import main

    for argv in (["ensemble", "--preset", "smok", "--out", "x"],
                 ["simulate", "--preset", "smok", "--seed", "1", "--out", "x.h5"],
                 ["config", "--preset", "smok"]):
        with pytest.raises(SystemExit) as e:
            main(argv)
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert "invalid choice: 'smok'" in err and all(f"'{p}'" in err for p in config.ALL_PRESET_NAMES), err


def test_a_preset_without_a_name_of_its_own_is_a_preset_of_the_commands(capsys):
    from tiltpile.cli import main

    assert main(["config", "--preset", "smoke-5x-dem", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["hash"] == config.load("smoke-5x-dem").hash()


# ------------------------------------------------------------------------------------------------
# the Makefile


def test_the_makefile_keeps_no_table_of_the_presets():
    assert not re.search(r"^RUNS_\S+ :?=", MAKEFILE, re.M)
    assert not re.search(r"^(REPORT_SCALES|REPORT_COMPARED) :?= *[a-z]", MAKEFILE, re.M)
    assert "tiltpile.cli.presets" in MAKEFILE


def _recipes(r) -> str:
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def test_the_makefile_resolves_scale_history_and_engine_to_the_preset():
    axes = _recipes(make_dry("figures", "SCALE=paper", "HISTORY=5x", "ENGINE=dem"))
    assert axes == _recipes(make_dry("figures", "PRESET=paper-5x-dem"))
    assert "figures/paper-5x-dem" in axes
    assert _recipes(make_dry("figures", "SCALE=paper", "HISTORY=10x")) == \
        _recipes(make_dry("figures", "PRESET=paper-fast"))
    # the runs of a preset without a name of its own: its scale's, from the package
    smoke = _recipes(make_dry("figures", "SCALE=smoke", "HISTORY=5x", "ENGINE=dem", "FROM=runs"))
    assert 'test -n "4" ||' in smoke and "--preset smoke-5x-dem --runs 4 --out data/smoke-5x-dem" in smoke
    # make study's own HISTORY (preset|repose+D) is no axis
    study = _recipes(make_dry("study", "KEY=scene.mu", "VALUES=0.2 0.5", "SCALE=paper", "HISTORY=repose+1"))
    assert "--preset paper --runs 50" in study and "--history 'repose+1'" in study
    study = _recipes(make_dry("study", "KEY=scene.mu", "VALUES=0.2 0.5", "SCALE=paper", "HISTORY=5x"))
    assert "--preset paper-5x --runs 8" in study and "--history 'preset'" in study


@pytest.mark.parametrize("args, said", [
    (["SCALE=paper", "HISTORY=3x"], "SCALE=paper HISTORY=3x: unknown history '3x'; choose one of fresh, 10x, 5x, 1x"),
    (["ENGINE=lammps"], "ENGINE=lammps: unknown engine 'lammps'; choose one of cd, dem"),
    (["PRESET=paper", "SCALE=smoke"], "PRESET=paper is not smoke, the preset of SCALE=smoke"),
])
def test_the_makefile_refuses_a_bad_axis_in_one_line(args, said):
    r = make_dry("figures", *args)
    lines = [line for line in (r.stdout + r.stderr).splitlines() if line.strip()]
    assert r.returncode == 2 and len(lines) == 1 and said in lines[0], r.stdout + r.stderr


def test_make_reports_rewrites_the_reports_of_the_scales_of_the_table():
    text = _recipes(make_dry("reports"))
    inreport = [p.name for p in config.PRESET_TABLE if p.report and p.name != "default"]
    assert f"for s in {' '.join(inreport)}; do" in text


# ------------------------------------------------------------------------------------------------
# the docs


def test_the_readme_and_the_docs_list_the_presets_of_the_table():
    from tiltpile.report.blocks import preset_axes, presets

    readme = presets(ROOT / "figures")        # the README's table (a generated block) is made of these
    assert [r["name"] for r in readme] == list(config.PRESETS)
    assert {r["name"]: r["runs"] for r in readme} == {p.name: p.runs for p in config.PRESET_TABLE}
    assert {r["name"]: r["grains"] for r in readme} == {p.name: config.load(p.name).scene.n
                                                        for p in config.PRESET_TABLE}
    assert {r["name"]: r["engine"] for r in readme} == {
        p.name: "DEM" if config.load(p.name).dem is not None else "CD" for p in config.PRESET_TABLE}
    rows = preset_axes(ROOT / "figures")      # docs/presets.md's table (generated): every triple
    assert [r["name"] for r in rows] == _axes_order()
    assert "<!-- generated: presets_table (tiltpile docs; do not edit) -->" in (ROOT / "docs" / "presets.md").read_text()
    cli = _table_rows(ROOT / "docs" / "cli.md", "## Presets")    # docs/cli.md: the aliases
    assert [r[0] for r in cli] == list(config.PRESETS)
    assert {r[0]: tuple(r[1:4]) for r in cli} == {p.name: (p.scale, p.history, p.engine)
                                                  for p in config.PRESET_TABLE}


def test_every_committed_figures_directory_is_not_ignored_by_git():
    """What a preset's `make figures` writes (its JSON, PNGs, records, report) and the friction
    study the report reads are committed: git must not ignore them (figures/*/ is ignored, so
    each needs its exception in .gitignore; the friction study's records once were refused)."""
    import shutil

    from tiltpile.report import friction

    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    paths = [f"{p.figures}/fig2_avalanche_criterion.json" for p in config.PRESET_TABLE]
    # the records of every scale but the default one (whose runs are cheap to recompute)
    paths += [f"{p.figures}/records/run_0000.npz" for p in config.PRESET_TABLE if p.figures != "figures"]
    paths += [f"figures/{friction.STUDY}", f"figures/{friction.STUDY.parent}/records/0.5/run_0000.npz"]
    r = subprocess.run(["git", "check-ignore", "--no-index", *paths], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.stdout.split() == [], f"ignored by .gitignore: {r.stdout.split()}"


def _scratch(tmp_path) -> Path:
    """What make reads of the checkout (the Makefile, the sources and notebooks, linked), and
    nothing it builds: no .venv, no data, no figures."""
    for name in ("Makefile", "environment.txt", "pyproject.toml"):
        (tmp_path / name).write_bytes((ROOT / name).read_bytes())
    for name in ("src", "notebooks"):
        (tmp_path / name).symlink_to(ROOT / name, target_is_directory=True)
    return tmp_path


@pytest.mark.parametrize("args", [["figures", "PRESET=smok"], ["figures", "PRESET=nope", "FROM=records"],
                                  ["figures/nope/fig1_isostaticity.json", "PRESET=nope"],
                                  ["ensemble", "PRESET=smok"],
                                  ["study", "KEY=scene.mu", "VALUES=0.2", "PRESET=smok"]])
def test_an_unknown_preset_is_answered_with_the_presets_before_anything_is_done(tmp_path, args):
    """`make figures PRESET=smok` (and the other targets that take a preset) names the presets in
    one line and stops before installing, locking or writing anything (when make reads the
    Makefile, without the venv: the presets come from the package's sources)."""
    tree = _scratch(tmp_path)
    r = subprocess.run(["make", *args], cwd=tree, capture_output=True, text=True, timeout=120, env=MAKE_ENV)
    assert r.returncode == 2, r.stdout + r.stderr
    name = next(a for a in args if a.startswith("PRESET=")).split("=")[1]
    said = [line for line in (r.stdout + r.stderr).splitlines() if "unknown PRESET" in line]
    assert len(said) == 1, r.stdout + r.stderr
    assert f"unknown PRESET={name}: the presets are {' '.join(sorted(config.ALL_PRESET_NAMES))} " in said[0]
    assert sorted(p.name for p in tree.iterdir()) == ["Makefile", "environment.txt", "notebooks",
                                                       "pyproject.toml", "src"]


def test_make_reads_the_presets_only_for_the_goals_that_need_them(tmp_path):
    """`make setup`, `make test`, `make docs` read no preset (the venv need not exist); a goal
    that takes a preset reads them once."""
    (tmp_path / "tree").mkdir()
    tree = _scratch(tmp_path / "tree")
    log = tmp_path / "calls"
    wrapper = tmp_path / "python"
    wrapper.write_text(f"#!/bin/sh\necho \"$@\" >> {log}\nexec {sys.executable} \"$@\"\n")
    wrapper.chmod(0o755)
    for goal, calls in (("setup", 0), ("test", 0), ("docs", 0), ("ensemble", 1)):
        log.write_text("")
        r = subprocess.run(["make", "-n", goal, f"PYTHON={wrapper}", "PRESET=paper-5x"], cwd=tree,
                           capture_output=True, text=True, timeout=120, env=MAKE_ENV)
        assert r.returncode == 0, r.stdout + r.stderr
        assert log.read_text().count("tiltpile.cli.presets") == calls, (goal, log.read_text())
