"""Facts the README and the docs both state, stated the same: the paper ensemble's cost and
whether the 4000-grain pile flows before its large slide (docs/performance.md is the measurement
log; the README and docs/slurm.md quote its current estimates)."""

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
    now = _section(PERF, "## Where things stand")
    for where, text in (("README.md", README), ("docs/performance.md", now), ("docs/slurm.md", SLURM)):
        one = " ".join(text.split())
        assert "1.5-3 hours" in one and "75-150 core-hours" in one, where
        assert "20-30 min" in one, where          # a fresh paper run


def test_the_capped_pile_is_not_called_a_flow():
    now = " ".join(_section(PERF, "## Where things stand").split())
    readme = " ".join(README.split())
    assert "not flowing there" in now and "It is not flowing there" in readme
    assert "1e-5 to 5e-4" in now and "1e-5 to 5e-4" in readme
