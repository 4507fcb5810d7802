"""The presets and scales are one list, ``config.PRESET_TABLE``: what the Makefile, the README
and docs/cli.md say of them is what it says (make cannot import it, so this test equates them)."""

import re
from pathlib import Path

import pytest

from tiltpile import config
from tiltpile.report import document, scales

ROOT = Path(__file__).resolve().parents[2]
MAKEFILE = (ROOT / "Makefile").read_text()


def _make_var(name: str) -> str:
    m = re.search(rf"^{re.escape(name)} := (.*)$", MAKEFILE, re.M)
    assert m, f"the Makefile defines no {name}"
    return m.group(1).strip()


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


def test_every_preset_has_its_toml_file_and_its_figures_directory_name():
    names = [p.name for p in config.PRESET_TABLE]
    assert len(set(names)) == len(names) and tuple(names) == config.PRESETS
    for p in config.PRESET_TABLE:
        assert config.load(p.name).scene.n > 0 and p.runs >= 1
        assert p.report in ("claims", "fig2", "")
        assert p.figures == "figures" if p.name == "default" else p.figures == f"figures/{p.name}"
    assert config.preset_info("paper").runs == 50
    try:
        config.preset_info("nope")
    except config.ConfigError as e:
        assert "unknown preset 'nope'" in str(e) and "paper-fast" in str(e)
    else:
        raise AssertionError("an unknown preset was accepted")


def test_the_makefile_runs_each_preset_as_the_table_says():
    for p in config.PRESET_TABLE:
        assert _make_var(f"RUNS_{p.name}") == str(p.runs), p.name
    given = set(re.findall(r"^RUNS_(\S+) :=", MAKEFILE, re.M))
    assert given == set(config.PRESETS), "the Makefile's RUNS_<preset> name other presets than config's"


def test_the_makefile_and_the_report_read_the_same_scales():
    inreport = [p.name for p in config.PRESET_TABLE if p.report and p.name != "default"]
    compared = [p.name for p in config.PRESET_TABLE if p.report == "claims" and p.name != "default"]
    assert _make_var("REPORT_SCALES").split() == inreport
    assert _make_var("REPORT_COMPARED").split() == compared
    assert [s for s, _ in scales.SCALES] == [p.name for p in config.PRESET_TABLE if p.report]
    assert list(document.COMPARED) == ["default"] + compared
    assert dict(scales.SCALES)["default"] == "" and dict(scales.SCALES)["paper"] == "paper"
    for what, a, b in document.CONTRASTS:     # a pair of presets of the table, of a known kind
        assert what in document.KINDS and {a, b} <= set(config.PRESETS)


def test_the_readme_and_the_cli_doc_list_the_presets_of_the_table():
    from tiltpile.report.blocks import presets

    readme = presets(ROOT / "figures")        # the README's table (a generated block) is made of these
    assert [r["name"] for r in readme] == list(config.PRESETS)
    assert {r["name"]: r["runs"] for r in readme} == {p.name: p.runs for p in config.PRESET_TABLE}
    assert {r["name"]: r["grains"] for r in readme} == {p.name: config.load(p.name).scene.n
                                                        for p in config.PRESET_TABLE}
    assert {r["name"]: r["engine"] for r in readme} == {
        p.name: "DEM" if config.load(p.name).dem is not None else "CD" for p in config.PRESET_TABLE}
    cli = _table_rows(ROOT / "docs" / "cli.md", "## Presets")
    assert [r[0] for r in cli] == list(config.PRESETS)
    assert {r[0]: r[1] for r in cli} == {p.name: str(config.load(p.name).scene.n)
                                         for p in config.PRESET_TABLE}


def test_every_committed_figures_directory_is_not_ignored_by_git():
    """What a preset's `make figures` writes (its JSON, PNGs, records, report) and the friction
    study the report reads are committed: git must not ignore them (figures/*/ is ignored, so
    each needs its exception in .gitignore; the friction study's records once were refused)."""
    import shutil
    import subprocess

    from tiltpile.report import friction

    if shutil.which("git") is None or not (ROOT / ".git").exists():
        import pytest
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
    Makefile)."""
    import subprocess

    from makehelpers import MAKE_ENV

    tree = _scratch(tmp_path)
    r = subprocess.run(["make", *args], cwd=tree, capture_output=True, text=True, timeout=120, env=MAKE_ENV)
    assert r.returncode == 2, r.stdout + r.stderr
    name = next(a for a in args if a.startswith("PRESET=")).split("=")[1]
    said = [line for line in (r.stdout + r.stderr).splitlines() if "unknown PRESET" in line]
    assert len(said) == 1, r.stdout + r.stderr
    assert f"unknown PRESET={name}: the presets are {' '.join(sorted(config.PRESETS))} " in said[0]
    assert sorted(p.name for p in tree.iterdir()) == ["Makefile", "environment.txt", "notebooks",
                                                       "pyproject.toml", "src"]


def test_the_commands_answer_an_unknown_preset_with_the_presets(capsys):
    from tiltpile.cli import main

    for argv in (["ensemble", "--preset", "smok", "--out", "x"],
                 ["simulate", "--preset", "smok", "--seed", "1", "--out", "x.h5"],
                 ["config", "--preset", "smok"]):
        with pytest.raises(SystemExit) as e:
            main(argv)
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert "invalid choice: 'smok'" in err and all(f"'{p}'" in err for p in config.PRESETS), err
