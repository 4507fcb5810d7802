"""One source for the run file's layout: ``store.LAYOUT`` (datasets) and ``store.ATTRS`` (the
attributes of the root and of the attribute-only groups) are what the writer writes, and
docs/run-file.md lists every one of them (datasets with their units); the store package's
docstring points to them instead of keeping a third copy."""

from __future__ import annotations

import re
from pathlib import Path

import h5py
import pytest

from tiltpile import config, store
from tiltpile.runner import simulate

DOC = Path(__file__).resolve().parents[2] / "docs" / "run-file.md"
# a tiny run with a preparation history, so that every group is written
TINY = ["scene.n=60", "scene.box_length=10.0", "protocol.theta_max_deg=0.5",
        "protocol.pretilt_deg=[0.5, 0.0]"]


def _doc_block() -> tuple[dict, dict]:
    """The layout block of docs/run-file.md: ({dataset: units}, {group: [attribute names]})."""
    text = DOC.read_text()
    block = text[text.index("```\n/ ") + 4:]
    block = block[:block.index("```")]
    datasets, attrs, group = {}, {}, None
    for line in block.splitlines():
        if line.startswith("/"):
            path = line.split()[0]
            if "attrs" in line:
                group = path.strip("/") or "/"
                attrs[group] = []
            else:
                group = None
                units = re.search(r"\[([^\]]+)\]", line)
                datasets[path.strip("/")] = units.group(1) if units else None
        elif group is not None and re.match(r"  \w", line):
            attrs[group].append(line.split()[0])
    return datasets, attrs


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("layout") / "run.h5"
    simulate(config.load("smoke", overrides=TINY), 1, out, progress=False)
    return out


def test_the_writer_writes_what_layout_and_attrs_declare(written):
    with h5py.File(written, "r") as f:
        found = []
        f.visititems(lambda name, obj: found.append(name) if isinstance(obj, h5py.Dataset) else None)
        assert sorted(found) == sorted(store.LAYOUT)
        for group, names in store.ATTRS.items():
            obj = f[group]
            if names is None:             # keys of another module's record (health)
                assert len(obj.attrs) > 0
                continue
            assert sorted(obj.attrs) == sorted(names), group


def test_the_doc_lists_every_dataset_with_its_units_and_every_attribute():
    datasets, attrs = _doc_block()
    assert set(datasets) == set(store.LAYOUT)
    for name, (units, _) in store.LAYOUT.items():
        assert datasets[name] == units, f"docs/run-file.md gives /{name} [{datasets[name]}], LAYOUT [{units}]"
    assert set(attrs) == set(store.ATTRS)
    for group, names in store.ATTRS.items():
        if names is not None:
            assert attrs[group] == list(names), f"docs/run-file.md: attributes of {group}"


def test_the_store_docstring_points_to_the_layout_instead_of_copying_it():
    doc = store.__doc__
    assert "LAYOUT" in doc and "ATTRS" in doc and "docs/run-file.md" in doc
    assert not any(f"/{name}" in doc for name in store.LAYOUT)
