"""The Makefile stays short (issue 71): what its targets do is said in docs/cli.md ("Make
targets"), which names every target a user runs, and the Makefile keeps one-line comments
pointing there."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAKEFILE = (ROOT / "Makefile").read_text()
MAX_LINES = 260
# the targets the others depend on, not run by hand
INTERNAL = {"FORCE", "build-lock", "check-nb", "preparation-runs"}


def test_the_makefile_is_at_most_260_lines():
    lines = MAKEFILE.splitlines()
    assert len(lines) <= MAX_LINES, f"the Makefile is {len(lines)} lines; at most {MAX_LINES}"


def test_docs_cli_names_every_target_a_user_runs():
    phony = re.search(r"^\.PHONY:((?:.*\\\n)*.*)$", MAKEFILE, re.M)
    assert phony, "no .PHONY line"
    targets = set(phony.group(1).replace("\\\n", " ").split()) - INTERNAL
    assert {"setup", "test", "figures", "study"} <= targets
    make = (ROOT / "docs" / "cli.md").read_text().split("## Make targets", 1)[1]
    missing = sorted(t for t in targets if not re.search(rf"\bmake {re.escape(t)}\b", make))
    assert missing == [], f"targets missing from docs/cli.md, \"Make targets\": {missing}"
