"""Other codes' frames into run files: ``tiltpile import`` (docs/import.md).

The analysis (``tiltpile observables``, ``record``, the figures and the report) reads run files
(docs/run-file.md). This package turns a tilted pile simulated or measured elsewhere into one:
LAMMPS text dumps as granular users write them, or the plain format (one NPZ file per frame, or
a CSV set of three tables). Every frame is checked against the format before anything is
written; a refusal is one line naming the field and the frame (``InputError``).

Modules: ``frame`` (one frame: ``RawFrame`` as read, ``Converter`` checking it and turning it
into a run file's frame, ``InputError``), ``lammps`` (``LammpsReader``: dump custom of atoms,
dump local of contacts, fix wall/gran contact arrays), ``plain`` (``NpzReader``,
``CsvReader``: the plain format) and ``run`` (``import_run``: the check, the configuration it
records, the write through the store's writer, whole or not at all).

``reader(inputs, ...)`` picks the reader from the inputs: ``.npz`` files (or a directory of
them), a directory holding ``frames.csv``, or LAMMPS dumps (files starting with ``ITEM:``).
"""

from __future__ import annotations

from pathlib import Path

from tiltpile.importers.frame import DEFAULT_EPS, Converter, InputError, RawFrame, Units
from tiltpile.importers.lammps import LammpsReader, is_dump
from tiltpile.importers.plain import CsvReader, NpzReader, kind_of
from tiltpile.importers.run import derived_config, import_run

__all__ = ["DEFAULT_EPS", "Converter", "CsvReader", "InputError", "LammpsReader", "NpzReader",
           "RawFrame", "Units", "derived_config", "detect", "import_run", "reader"]


def detect(inputs) -> str:
    """The format of ``inputs``: "npz", "csv" or "lammps"; InputError when it is none of them."""
    paths = [Path(p) for p in inputs]
    if not paths:
        raise InputError("give the frames to import")
    for p in paths:
        if not p.exists():
            raise InputError(f"{p}: no such file or directory")
    kind = kind_of(paths)
    if kind is not None:
        return kind
    if all(p.is_file() and is_dump(p) for p in paths):
        return "lammps"
    bad = next((p for p in paths if not (p.is_file() and (p.suffix == ".npz" or is_dump(p)))), paths[0])
    raise InputError(f"{bad}: neither a LAMMPS text dump (ITEM: lines), an .npz frame, a directory "
                     "of .npz frames nor a directory holding frames.csv, grains.csv and "
                     "contacts.csv (docs/import.md)")


def reader(inputs, *, box_length: float, **lammps_options):
    """The reader of ``inputs`` (``detect``); ``lammps_options`` (``LammpsReader``'s keywords,
    ``contacts`` among them) for LAMMPS dumps only: given with plain-format inputs, refused."""
    kind = detect(inputs)
    if kind == "lammps":
        return LammpsReader(inputs, box_length=box_length, **lammps_options)
    given = sorted(k for k, v in lammps_options.items() if v not in (None, (), [], "", {}))
    if given:
        raise InputError(f"--{given[0].replace('_', '-')} is for LAMMPS dumps; the inputs are "
                         f"the plain format ({kind})")
    return NpzReader(inputs) if kind == "npz" else CsvReader(inputs)
