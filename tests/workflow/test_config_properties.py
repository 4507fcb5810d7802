"""Property-based tests of the configuration: any value of any field either validates
or is refused with a message naming the field, and a refused command writes nothing."""

from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tiltpile import config
from tiltpile.cli import main

FIELDS = [(section, f.name) for section, cls in config.SECTIONS.items() for f in dataclasses.fields(cls)]

VALUES = st.one_of(
    st.integers(min_value=-(10**30), max_value=10**30),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-10, max_value=10),
    st.booleans(),
    st.text(max_size=12),
    st.sampled_from(["forward", "interleaved", "random", "alternating"]),
    st.lists(st.one_of(st.floats(allow_nan=True), st.integers(-100, 100), st.booleans()), max_size=4),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)

# TOML value texts as a user types them after --set section.key=
TEXTS = st.one_of(
    st.integers(min_value=-(10**25), max_value=10**25).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["true", "false", "nan", "inf", "-inf", "1e400", "-0.0", "[]", "[1, 2.5]", "[0.0]",
                     '"forward"', "forward", "{a = 1}", "", "1_000", "0x10", "1" + "0" * 400, "[1e400]"]),
    st.text(max_size=10),
)


def _named(message: str, section: str, key: str) -> bool:
    return f"{section}.{key}" in message


@settings(max_examples=400, deadline=None)
@given(field=st.sampled_from(FIELDS), value=VALUES)
def test_any_value_validates_or_is_refused_naming_its_field(field, value):
    section, key = field
    data = config._merge(config.preset_dict("smoke"), {section: {key: value}})
    try:
        cfg = config.from_dict(data)
    except config.ConfigError as e:
        assert _named(str(e), section, key), str(e)
        return
    got = getattr(getattr(cfg, section), key)
    if isinstance(got, float):
        assert math.isfinite(got)
    assert config.from_json(cfg.to_json()) == cfg  # what a run file stores reads back the same
    assert len(cfg.hash()) == 64


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(FIELDS), text=TEXTS)
def test_a_refused_override_writes_nothing(tmp_path_factory, monkeypatch, capsys, field, text):
    """`tiltpile simulate --set SECTION.KEY=TEXT`: exit 2 with one line naming the field and an
    untouched directory, or (valid) the simulation is called (here a stub)."""
    import tiltpile.runner

    section, key = field
    calls = []
    monkeypatch.setattr(tiltpile.runner, "simulate", lambda *a, **k: calls.append(a) or {})
    d = tmp_path_factory.mktemp("out")
    capsys.readouterr()
    rc = main(["simulate", "--preset", "smoke", "--set", f"{section}.{key}={text}", "--seed", "1",
               "--out", str(d / "run.h5"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    if rc == 2:
        assert len(err) == 1 and _named(err[0], section, key), err
        assert not calls
    else:
        assert rc == 0 and len(calls) == 1, err
    assert list(d.iterdir()) == []


@pytest.mark.parametrize("text", ["1" + "0" * 400, "1e400", "[1e400]"])
def test_overflowing_numbers_are_refused_naming_the_field(text):
    with pytest.raises(config.ConfigError, match=r"solver\.dt"):
        config.load("smoke", overrides=[f"solver.dt={text}"])
