"""Edits of a scratch copy of the package's code, shared by the tests of the columns' digests
(tests/analysis/test_analysis_tables.py) and of records surviving analysis edits
(tests/workflow/test_records_survive_edits.py)."""

from __future__ import annotations

from pathlib import Path

# a column added by a test: one producer and its declaration, nothing else touched
NEW_COLUMN = """

@_produces("frame", gives=("frames.n_wall_contacts",), reads=("contacts",))
def _wall_contacts(q):
    return {"frames.n_wall_contacts": int((q["contacts"]["pair"][:, 1] < 0).sum())}

"""
ENGINE_MARK = ("# ----------------------------------------------------------------------------------------------\n"
               "# the engine")


def edit(path: Path, old: str, new: str) -> None:
    """Replace the first ``old`` of file ``path`` by ``new`` (``old`` must be there)."""
    text = path.read_text()
    assert old in text, f"{path.name}: {old!r}"
    path.write_text(text.replace(old, new, 1))


def add_column(src: Path) -> None:
    """Declare and produce a new per-frame column, n_wall_contacts, in the copy ``src`` of src/."""
    t = src / "tiltpile" / "analysis" / "tables.py"
    edit(t, '    "max_displacement": ', '    "n_wall_contacts": "active contacts with a wall",\n'
         '    "max_displacement": ')
    edit(t, ENGINE_MARK, NEW_COLUMN + ENGINE_MARK)
