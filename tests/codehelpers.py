"""Edits of a scratch copy of the package's code, shared by the tests of the columns' codes
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


# a refactor that changes no value: the kinetic-energy producer moved to a module of its own,
# its helper renamed and moved with it
ENERGY_MODULE = '''"""The kinetic energy of the grains (moved out of tables.py by a test's refactor)."""

import numpy as np

from .tables import _produces


def grain_energies(radius, velocity, omega):
    r = np.asarray(radius, dtype=float)
    m = np.pi * r * r
    v = np.asarray(velocity, dtype=float).reshape(-1, 2)
    return 0.5 * m * (v[:, 0] ** 2 + v[:, 1] ** 2), 0.25 * m * r * r * np.asarray(omega, dtype=float) ** 2


@_produces("frame", gives=("frames.ke_trans", "frames.ke_rot"),
           reads=("radius", "velocity", "omega", "fixed"))
def _mean_energies(q):
    e_t, e_r = grain_energies(q["radius"], q["velocity"], q["omega"])
    mobile = ~q["fixed"]
    n_mobile = int(mobile.sum())
    return {"frames.ke_trans": float(e_t[mobile].mean()) if n_mobile else np.nan,
            "frames.ke_rot": float(e_r[mobile].mean()) if n_mobile else np.nan}
'''


def refactor(src: Path) -> None:
    """Move the kinetic-energy producer of the copy ``src`` of src/ to analysis/energy.py, where
    it calls a helper of another name (the same arithmetic as contacts.kinetic_energy, rewritten);
    tables.py imports the module where the producer stood; and rename tables.py's helper
    ``_float32`` (two producers call it)."""
    t = src / "tiltpile" / "analysis" / "tables.py"
    text = t.read_text()
    start = text.index('@_produces("frame", gives=("frames.ke_trans", "frames.ke_rot"),')
    end = text.index("@_produces", start + 10)
    text = (text[:start] + "from . import energy as _energy_module  # noqa: E402,F401\n\n\n"
            + text[end:])
    assert text.count("_float32(") == 3
    t.write_text(text.replace("_float32(", "_held_to_single_precision("))
    (src / "tiltpile" / "analysis" / "energy.py").write_text(ENERGY_MODULE)
