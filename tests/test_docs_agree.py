"""Facts the README and the docs both state, stated the same: the paper ensemble's cost and
whether the 4000-grain pile flows before its large slide (the "Where things stand" of
docs/performance.md summarizes the measurement log, docs/performance-log.md; the README and
docs/slurm.md quote its current estimates)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
PERF = (ROOT / "docs" / "performance.md").read_text()
SLURM = (ROOT / "docs" / "slurm.md").read_text()


def _section(text: str, heading: str) -> str:
    start = text.index(heading)
    end = text.find("\n## ", start + len(heading))
    return text[start:end if end > 0 else None]


def test_the_paper_ensembles_cost_is_the_same_everywhere():
    """The estimate of docs/performance.md's "Where things stand" (hours per cycled run and
    core-hours for 50) is the one the README and docs/slurm.md quote, and no other is quoted."""
    import re

    now = " ".join(_section(PERF, "## Where things stand").split())
    m = re.search(r"an estimated (\d+(?:\.\d+)?-\d+(?:\.\d+)?) hours on one core, "
                  r"(\d+-\d+) core-hours for the paper's 50", now)
    assert m, "docs/performance.md states no estimate for the paper ensemble"
    hours, core_hours = m.groups()
    for where, text in (("README.md", README), ("docs/slurm.md", SLURM)):
        one = " ".join(text.split())
        assert f"{hours} hours" in one and f"{core_hours} core-hours" in one, where
        quoted = set(re.findall(r"(\d+(?:\.\d+)?-\d+(?:\.\d+)?) (?:core-)?hours (?:per run|on one)", one))
        assert quoted <= {hours}, (where, quoted)
    for where, text in (("README.md", README), ("docs/performance.md", now), ("docs/slurm.md", SLURM)):
        assert "20-30 min" in " ".join(text.split()), where          # a fresh paper run


def test_the_capped_pile_is_not_called_a_flow():
    now = " ".join(_section(PERF, "## Where things stand").split())
    readme = " ".join(README.split())
    assert "not flowing there" in now and "It is not flowing there" in readme
    assert "1e-5 to 5e-4" in now and "1e-5 to 5e-4" in readme
