"""Parameters that explain themselves (issue 74, items 3 and 4): ``tiltpile config`` lists every
key of every section with its meaning, unit, value, default and allowed range, from the field
docs and ranges ``config.py`` validates with; docs/cli.md's table is rendered from the same
function (its freshness: tests/test_docs_agree.py); the docs gave every key a unit without
changing a preset's hash; the pile's depth is printed; make names the presets for an unknown one."""

from __future__ import annotations

import dataclasses
import re
import subprocess
from pathlib import Path

import pytest

from makehelpers import MAKE_ENV
from tiltpile import config
from tiltpile.cli import main

ROOT = Path(__file__).resolve().parents[2]

# config.load(p).hash() of every preset before the field docs were given their units: a doc is
# no part of a configuration, and no preset may change its hash
PRESET_HASHES = {
    "smoke": "f49370597528a8b88c21a922177848bf7c071db6498e246454e325477aabad4b",
    "default": "f822c0f99af72f0c8da3302a44e7d660a0c62eb05b4e5a98ffd9574cfc500d35",
    "default-fresh": "fa89eabe20039391233ca3edd2e2f81223b95834369b7fe5fc429ec5c4b9cab4",
    "default-dem": "fef535b935c8e305106e9e2940f7c958f2da0f785a2ceddce57509dd7599964e",
    "paper": "c22bab2311c253f67c59980e57c69b21f88d4641f43fc6483d0ad3446febec45",
    "paper-fresh": "a2a1ff442489581b9729b5f8762364db20e874617725d57ef624e98699008f41",
    "paper-fast": "643332a7b7ebbc02a2129f2afda3477a55727905d68eeadeadacc86c6010997c",
    "paper-fast-dem": "0e94b4b0b5fdf17446860d18b7fc72e1fb53e4c3f0a847a1308f67378a2d0bbf",
    "paper-5x": "33a10832a3dc3792d15bda98bb010c9a25e5c91c6bb62f6b9d3df4f733678ed1",
    "paper-5x-dem": "8146bde83dee338ebcff2693c62a38507a80675f4980716cef3805d3d48c56c9",
    "paper-dem": "ceaddbad3df04739f743e91d6b8e983d2ce3abe6bf5c0f9fc17eb22c68afd6b4",
}


def _config(capsys, *argv) -> tuple[int, str, str]:
    status = main(["config", *argv])
    out = capsys.readouterr()
    return status, out.out, out.err


def _fields():
    return [(section, f) for section, cls in config.SECTIONS.items()
            for f in dataclasses.fields(cls)]


def test_no_preset_changed_its_hash():
    assert {p: config.load(p).hash() for p in config.PRESETS} == PRESET_HASHES


def test_every_field_doc_gives_a_meaning_and_ends_with_its_unit():
    docs = [f.metadata["doc"] for _, f in _fields()] + list(config.HISTORY_SHORTHAND.values())
    for doc in docs:
        meaning, unit = config.split_doc(doc)
        assert len(meaning) > 5 and unit.strip() == unit and unit, doc
    with pytest.raises(config.ConfigError, match="unit"):
        config.split_doc("a doc without its unit")


def test_describe_keys_lists_every_field_of_every_section_and_the_shorthand():
    rows = config.describe_keys(config.load("paper"))
    keys = [r["key"] for r in rows]
    fields_ = [f"{s}.{f.name}" for s, f in _fields()]
    shorthand = [f"protocol.{k}" for k in config.HISTORY_SHORTHAND]
    assert sorted(keys) == sorted(fields_ + shorthand) and len(set(keys)) == len(keys)
    by_key = {r["key"]: r for r in rows}
    assert by_key["scene.n"]["value"] == "4000" and by_key["scene.n"]["default"] == "1000"
    assert by_key["scene.n"]["unit"] == "grains" and by_key["solver.dt"]["unit"] == "sqrt(d/g)"
    assert by_key["solver.dt"]["range"] == "(0.0, 1.0]"
    assert by_key["dem.kn"]["value"] is None and by_key["dem.kn"]["optional"]  # no dem section
    assert by_key["protocol.cycles"]["shorthand"] and by_key["protocol.cycles"]["default"] is None
    for r in rows:
        assert r["meaning"] and r["unit"] and r["range"] and r["type"], r


def test_the_shorthand_ranges_listed_are_the_ones_checked():
    assert config.describe_keys()[0]["key"] == "scene.n"
    ok = {"protocol": {"cycles": 100, "theta_rev_deg": 90.0}}
    assert config.from_dict(ok).protocol.pretilt_deg[0] == 90.0
    for bad in ({"cycles": 101, "theta_rev_deg": 16.0}, {"cycles": 2, "theta_rev_deg": 90.5}):
        with pytest.raises(config.ConfigError):
            config.from_dict({"protocol": bad})


def _listed(out: str) -> dict[str, tuple[str, str]]:
    """{section.key: (its line, the comment lines above it joined)} of ``tiltpile config``'s
    text, commented-out keys (an absent section, the shorthand) included."""
    listed, section, comment = {}, None, []
    for line in out.splitlines():
        header = re.fullmatch(r"(# )?\[(\w+)\]", line)
        key = re.match(r"(# )?(\w+) = ", line)
        if header:
            section, comment = header.group(2), []
        elif key and section:
            listed[f"{section}.{key.group(2)}"] = (line, " ".join(comment))
            comment = []
        elif line.startswith("# "):
            comment.append(line[2:])
        else:
            comment = []
    return listed


@pytest.mark.parametrize("preset", ["smoke", "paper", "default-dem"])
def test_tiltpile_config_prints_every_key_with_meaning_unit_range_and_default(capsys, preset):
    status, out, err = _config(capsys, "--preset", preset)
    assert status == 0 and err == ""
    cfg = config.load(preset)
    listed = _listed(out)
    rows = config.describe_keys(cfg)
    assert sorted(listed) == sorted(r["key"] for r in rows)
    for r in rows:
        line, meaning = listed[r["key"]]
        assert meaning.startswith(" ".join(r["meaning"].split())), (r["key"], meaning)
        assert f"  # [{r['unit']}]  allowed {r['range']}  " in line, line
        if r["shorthand"]:
            assert line.startswith("# ") and line.endswith("(not set)")
            continue
        value = r["value"] if r["value"] is not None else r["default"]
        assert line.startswith(("# " if r["value"] is None else "") + f"{r['name']} = {value}  # ")
        assert line.endswith("(default)" if value == r["default"] else f"default {r['default']}")
    assert ("# [dem]" in out.splitlines()) == (cfg.dem is None)
    assert f"# tiltpile configuration: preset {preset}" in out and cfg.hash() in out


@pytest.mark.parametrize("preset", ["paper", "default-dem", None])
def test_the_listing_is_a_toml_file_of_the_same_configuration(capsys, tmp_path, preset):
    status, out, _ = _config(capsys, *(["--preset", preset] if preset else []))
    f = tmp_path / "listed.toml"
    f.write_text(out)
    expected = config.load(preset) if preset else config.from_dict({})
    # over nothing (every key is given) and over another preset (the history replaces its shorthand)
    assert config.load_over({}, f).hash() == expected.hash()
    assert config.load("smoke", f).hash() == expected.hash()
    assert config.load("paper", f).hash() == expected.hash()


def test_set_values_are_listed_and_bad_ones_refused_in_one_line(capsys):
    status, out, _ = _config(capsys, "--preset", "smoke", "--set", "scene.mu=0.8")
    assert status == 0 and re.search(r"^mu = 0\.8  # \[-\]  allowed \[0\.0, inf\)  default 0\.5$", out, re.M)
    assert "--set scene.mu=0.8" in out.splitlines()[0]
    status, out, err = _config(capsys, "--set", "scene.mu=-1")
    assert status == 2 and out == ""
    assert err == "tiltpile config: error: scene.mu = -1.0 is out of range: allowed [0.0, inf)\n"
    status, _, err = _config(capsys, "--set", "scene.layers=20")
    assert status == 2 and "unknown key scene.layers" in err


def test_the_depth_is_derived_and_printed(capsys):
    d = config.describe_depth(config.load("default"))
    assert d["depth"] == pytest.approx(24.87, abs=0.01)   # a default pile measures 24.8 d
    assert d["n"] == pytest.approx(d["depth"] * d["grains_per_depth"])
    assert config.describe_depth(config.load("smoke"))["depth"] == pytest.approx(12.4, abs=0.05)
    _, out, _ = _config(capsys, "--preset", "paper")
    assert "# pile depth (derived; no key sets it): about 33.2 d above the rough bottom row" in out
    assert "scene.n = 120.6 H" in out
    _, out, _ = _config(capsys, "--json")
    assert '"depth": 24.87' in out and '"key": "dem.slide_eps"' in out


def test_the_cli_doc_tables_every_key():
    doc = (ROOT / "docs" / "cli.md").read_text()
    section = doc.split("## Configuration keys", 1)[1].split("\n## ", 1)[0]
    assert "<!-- generated: cli_keys (tiltpile docs; do not edit) -->" in section
    for r in config.describe_keys():
        assert re.search(rf"^\| `{re.escape(r['key'])}` \| .+ \| {re.escape(r['unit'])} \| ",
                         section, re.M), r["key"]


@pytest.mark.parametrize("target", ["figures", "ensemble"])
def test_make_names_the_presets_for_an_unknown_one(target):
    """Answered when make reads the Makefile (so under -n too, before anything runs): one line
    naming every preset, exit status 2 (tests/workflow/test_presets.py: nothing is written)."""
    r = subprocess.run(["make", "-n", target, "PRESET=smok"], cwd=ROOT, capture_output=True,
                       text=True, env=MAKE_ENV, timeout=60)
    lines = [l for l in (r.stdout + r.stderr).splitlines() if "unknown PRESET=smok" in l]
    assert r.returncode == 2 and len(lines) == 1, r.stdout + r.stderr
    assert set(config.PRESETS) <= set(re.findall(r"[\w-]+", lines[0]))
    known = subprocess.run(["make", "-n", target, "PRESET=smoke"], cwd=ROOT, capture_output=True,
                           text=True, env=MAKE_ENV, timeout=60)
    assert known.returncode == 0 and 'test -n "4" ||' in known.stdout


def test_the_kernel_filter_drops_the_shutdown_interrupt_line_alone():
    import logging

    from tiltpile.figures import kernel

    log = logging.getLogger("test_config_keys.kernel")
    kernel.load_ipython_extension(type("Shell", (), {"kernel": type("K", (), {"log": log})()})())
    kernel.load_ipython_extension(type("Shell", (), {"kernel": type("K", (), {"log": log})()})())
    assert log.filters == [kernel.not_the_shutdown_interrupt]   # once, however often loaded

    def record(msg):
        return logging.LogRecord("IPKernelApp", logging.ERROR, __file__, 1, msg, None, None)

    assert not log.filter(record("KeyboardInterrupt caught in kernel."))
    assert not log.filter(record("KeyboardInterrupt caught in kernel"))
    assert log.filter(record("Exception in message handler:"))
    assert log.filter(record("KeyboardInterrupt caught in kernel. and more"))


def test_papermills_shutdown_interrupt_leaves_no_error_line(tmp_path):
    """The race made certain: the kernel's last kernel_info handler still runs when papermill's
    shutdown interrupts it, which the stock kernel logs as an ERROR line."""
    from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel

    try:
        spec = KernelSpecManager().get_kernel_spec("tiltpile")
    except NoSuchKernel:
        pytest.skip("no tiltpile kernel installed (make setup installs it)")
    assert "--IPKernelApp.extra_extensions=tiltpile.figures.kernel" in spec.argv, \
        "the tiltpile kernel spec predates the extension: rerun make setup's kernel step"
    code = ("import inspect, time\n"
            "k = get_ipython().kernel\n"
            "orig = k.shell_handlers['kernel_info_request']\n"
            "async def slow(stream, ident, parent):\n"
            "    r = orig(stream, ident, parent)\n"
            "    if inspect.isawaitable(r):\n"
            "        await r\n"
            "    time.sleep(1.0)\n"
            "k.shell_handlers['kernel_info_request'] = slow\n")
    from makehelpers import papermill_one_cell

    done, _ = papermill_one_cell(tmp_path, code)
    assert done.returncode == 0, done.stderr
    assert "IPKernelApp" not in done.stderr, done.stderr
