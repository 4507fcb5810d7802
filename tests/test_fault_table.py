"""docs/faults.md names, for each fault, the tests that show what the project does: every one
of them must exist (a renamed or deleted test would leave the table promising what nothing checks)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "faults.md"


def _rows() -> list[list[str]]:
    rows = []
    for line in PAGE.read_text().splitlines():
        if line.startswith("| ") and not line.startswith("| fault ") and not line.startswith("|---"):
            rows.append([c.strip() for c in line.strip("|").split(" | ")])
    return rows


def test_every_test_the_fault_table_names_exists():
    rows = _rows()
    assert len(rows) >= 15
    named = 0
    for fault, does, tests in rows:
        refs = re.findall(r"`(tests/[\w/]+\.py)::(test_\w+)`", tests)
        assert refs, f"no test named for {fault!r}"
        for path, name in refs:
            text = (ROOT / path).read_text()
            assert re.search(rf"^def {name}\(", text, re.M), f"{path}::{name} (for {fault!r}) does not exist"
            named += 1
    assert named >= 30


def test_the_table_covers_the_faults_issue_55_lists():
    faults = " ".join(r[0] for r in _rows())
    for words in ("history", "ramp", "write", "checkpoint", "record", "full disk", "two writers",
                  "two builds", "damaged record", "foreign record"):
        assert words in faults, words


def test_the_docs_index_links_the_fault_table():
    assert "(faults.md)" in (ROOT / "docs" / "README.md").read_text()
