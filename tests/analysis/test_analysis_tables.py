"""The tables' declarations and the digest of their code (tiltpile.analysis.tables)."""

import shutil
from pathlib import Path

import numpy as np
import pytest

import tiltpile.analysis.observables as ob
from tiltpile.analysis import tables
from tiltpile.analysis.tables import code_digest, table_code

ANALYSIS = Path(tables.__file__).parent


@pytest.fixture
def package(tmp_path):
    """A scratch copy of the analysis package's modules."""
    for f in ANALYSIS.glob("*.py"):
        shutil.copy2(f, tmp_path / f.name)
    return tmp_path


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, 1))


def test_digest_is_the_installed_tables_code(package):
    assert code_digest(package, "tables") == table_code() == code_digest(ANALYSIS, "tables")
    assert len(table_code()) == 16


def test_documentation_edits_keep_the_digest(package):
    before = code_digest(package, "tables")
    _edit(package / "contacts.py", '"""Active contacts: normal force f_n > 0.',
          '"""Active contacts: normal force f_n > 0 (edited).')
    _edit(package / "clusters.py", "from .contacts import contact_counts, dz_local",
          "# a new comment\nfrom .contacts import contact_counts, dz_local  # and another")
    _edit(package / "tables.py", '"""The observables\' tables:', '"""The tables (edited):')
    assert code_digest(package, "tables") == before


@pytest.mark.parametrize("module, old, new", [
    ("contacts.py", "return force[:, 0] > 0.0", "return force[:, 0] >= 0.0"),      # imported
    ("avalanche.py", "import warnings", "import warnings\n_NEW = 1"),             # imported
    ("tables.py", '"min_contacts": 2,', '"min_contacts": 3,'),                    # itself
])
def test_code_edits_change_the_digest(package, module, old, new):
    before = code_digest(package, "tables")
    _edit(package / module, old, new)
    assert code_digest(package, "tables") != before


def test_modules_the_tables_do_not_import_keep_the_digest(package):
    before = code_digest(package, "tables")
    (package / "structure.py").write_text((package / "structure.py").read_text() + "\n_X = 2\n")
    assert code_digest(package, "tables") == before


def test_every_column_is_declared_once_and_documented():
    assert tables.FRAME_COLUMNS == list(tables.FRAME_DOCS)
    assert tables.CLUSTER_COLUMNS == list(tables.CLUSTER_DOCS)
    for docs in (tables.FRAME_DOCS, tables.CLUSTER_DOCS):
        for name, doc in docs.items():
            assert doc.strip() and f"    {name} " in tables.__doc__
    # the observables module re-exports the declarations, it does not keep its own
    assert ob.FRAME_COLUMNS is tables.FRAME_COLUMNS and ob.DEFAULT_PARAMS is tables.DEFAULT_PARAMS


def test_frame_functions_take_the_parameters_by_name():
    radius = np.full(3, 0.5)
    fixed = np.array([True, False, False])
    pos = np.array([[0.5, 0.5], [1.5, 0.5], [1.0, 1.366]])
    pair = np.array([[0, 1], [0, 2], [1, 2]])
    force = np.array([[1.0, 0.0], [1.0, 0.5], [1.0, 0.0]])
    status = np.array([1, 1, 2], dtype=np.int8)
    with pytest.raises(TypeError, match=r"unknown analysis parameter\(s\) \['cut_off'\]"):
        tables.frame_contacts(radius, fixed, 3.0, pos, pair, force, status, cut_off=0.1)
    with pytest.raises(TypeError):     # keywords only: no parameter slips in by position
        tables.frame_contacts(radius, fixed, 3.0, pos, pair, force, status, 0.5)
    a = tables.frame_contacts(radius, fixed, 3.0, pos, pair, force, status)
    b = tables.frame_contacts(radius, fixed, 3.0, pos, pair, force, status, eps=0.01)
    assert a["mobilized"].tolist() == [False, False, True]   # the sliding status
    assert b["mobilized"].tolist() == [False, True, False]   # |f_t| >= mu f_n (1 - eps)



def test_the_rigidity_columns_of_a_frame(pile_factory, contacts_factory):
    """A triangular pile on its fixed row is one rigid cluster from the ground to the surface
    while its contacts stick; with every contact whose lower grain is in row 4 or above sliding
    (1 bar each), rows 5 and 6 come loose, rows 1-4 stay rigid with the ground (2 sticking
    contacts down each: 4 bars for 3 degrees of freedom), and nothing spans."""
    pos, radius, fixed, row = pile_factory(8, 6)
    L = 8.0
    pair = contacts_factory(pos, radius, L)
    force = np.column_stack([np.ones(len(pair)), np.zeros(len(pair))])
    zero = np.zeros_like(pos)

    def rigidity(status):
        r, _, _ = tables.frame_observables(radius, fixed, L, pos, zero, np.zeros(len(radius)),
                                           pair, force, status, 0.0)
        return r["rigid_fraction"], r["floppy_per_grain"], r["rigid_spanning"], r["n_rigid_left_out"]

    frac, floppy, spanning, left_out = rigidity(np.ones(len(pair), dtype=np.int8))
    assert (frac, floppy, spanning, left_out) == (1.0, 0.0, True, 0)
    top = row[pair[:, 0]] >= 4
    frac, floppy, spanning, _ = rigidity(np.where(top, 2, 1).astype(np.int8))
    n_mobile = int((~fixed).sum())
    assert frac == pytest.approx(((row >= 1) & (row <= 4)).sum() / n_mobile)
    assert floppy > 0 and not spanning
