"""LAMMPS text dumps as granular users write them (docs/import.md, "LAMMPS dumps").

Atoms: ``dump custom`` (or ``write_dump ... custom``) with at least id, x, y and radius (or
diameter); type (for ``--fixed-types``), vx vy and omegaz when present; the tilt angle as a
per-atom column (``theta``, or the gravity vector ``gx``, ``gy``) unless ``angles`` gives it;
the per-atom contact arrays of ``fix wall/gran ... contacts`` for the walls (``walls``).
Contacts: ``dump local`` of ``compute property/local patom1 patom2`` beside ``compute
pair/local force p1 p2 ...`` (the pair's ids, the normal force and the tangential force on
atom 1, as a vector or signed). One frame per ``ITEM: TIMESTEP`` block, in one file or many
(``atoms.*.dump``), gzip-compressed or not; frames are taken in timestep order and an atom frame
is joined to the contact frame of its timestep (contact frames at other timesteps are skipped).
"""

from __future__ import annotations

import gzip
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tiltpile.importers.frame import WALL_IDS, InputError, RawFrame, finite, flags, integers, label

# role -> the column read by default (None: only when mapped); docs/import.md lists them
ATOM_ROLES = {"id": "id", "type": "type", "x": "x", "y": "y", "radius": "radius",
              "diameter": "diameter", "vx": "vx", "vy": "vy", "omega": "omegaz", "theta": None,
              "gx": None, "gy": None}
CONTACT_ROLES = ("id1", "id2", "fn", "ft", "ftx", "fty", "sliding")
PLANES = ("floor", "left", "right", "sides")


def parse_mapping(text: str | None, roles, option: str) -> dict:
    """``"role=column,role=column"`` -> {role: column}; InputError naming the option for an
    unknown role, a role given twice or an entry without ``=``."""
    out: dict = {}
    for item in (text or "").split(","):
        item = item.strip()
        if not item:
            continue
        role, eq, column = (s.strip() for s in item.partition("="))
        if not eq or not role or not column:
            raise InputError(f"{option}: {item!r} is not ROLE=COLUMN")
        if role not in roles:
            raise InputError(f"{option}: unknown role {role!r}; the roles are {', '.join(roles)}")
        if role in out:
            raise InputError(f"{option}: role {role!r} is given twice")
        out[role] = column
    return out


def parse_walls(items) -> dict:
    """``["f_floor=floor", "f_sides=sides"]`` -> {column prefix: plane}."""
    out: dict = {}
    for item in items or ():
        name, eq, plane = (s.strip() for s in str(item).partition("="))
        if not eq or not name or plane not in PLANES:
            raise InputError(f"--wall {item!r}: expected FIX=PLANE, PLANE one of {', '.join(PLANES)} "
                             "(FIX: the dump's column prefix of a fix wall/gran ... contacts, "
                             "e.g. f_floor)")
        out[name] = plane
    return out


@dataclass
class DumpFrame:
    """One ``ITEM: TIMESTEP`` block of a dump: its columns and rows (all as float64)."""

    path: Path
    step: int
    time: float           # ITEM: TIME, NaN without it
    columns: list
    data: np.ndarray      # (rows, columns)

    @property
    def where(self) -> str:
        return f"{self.path.name}, step {self.step}"

    def column(self, name: str, role: str, option: str) -> np.ndarray:
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise InputError(f"{self.where}: no column {name!r} ({role}; {option}); its columns are "
                             f"{' '.join(self.columns)}") from None


def _open(path: Path):
    if path.suffix == ".gz":
        return gzip.open(path, "rt", errors="replace")
    return open(path, errors="replace")


def is_dump(path: Path) -> bool:
    """Whether ``path`` starts like a LAMMPS text dump (``ITEM:``)."""
    try:
        with _open(path) as fh:
            return fh.readline().startswith("ITEM:")
    except (OSError, EOFError, UnicodeDecodeError):
        return False


def dump_frames(path: Path, kind: str):
    """The frames of one dump file: ``kind`` "ATOMS" (dump custom) or "ENTRIES" (dump local);
    a file that cannot be read (a damaged .gz) is an InputError naming it."""
    try:
        yield from _dump_frames(Path(path), kind)
    except (OSError, EOFError) as e:
        raise InputError(f"{Path(path).name}: cannot be read ({' '.join(str(e).split())})") from None


def _dump_frames(path: Path, kind: str):
    other = {"ATOMS": "a dump local (ITEM: ENTRIES)", "ENTRIES": "a dump custom of atoms (ITEM: ATOMS)"}
    with _open(path) as fh:
        lines = iter(fh)
        step, time, rows, number = None, math.nan, None, 0
        for line in lines:
            number += 1
            text = line.strip()
            if not text:
                continue
            if not text.startswith("ITEM:"):
                raise InputError(f"{path.name}, line {number}: expected an ITEM: line, got {text[:40]!r}")
            item = text[5:].strip()
            try:
                if item == "TIMESTEP":
                    step, time, rows = int(next(lines).split()[0]), time, None
                    number += 1
                elif item == "TIME":
                    time = float(next(lines).split()[0])
                    number += 1
                elif item == "UNITS":
                    next(lines)
                    number += 1
                elif item.startswith("NUMBER OF"):
                    rows = int(next(lines).split()[0])
                    number += 1
                elif item.startswith("BOX BOUNDS"):
                    for _ in range(3):
                        next(lines)
                    number += 3
                elif item.split()[0] in ("ATOMS", "ENTRIES"):
                    if item.split()[0] != kind:
                        raise InputError(f"{path.name}: {other[kind]}, not the dump expected here")
                    if step is None or rows is None:
                        raise InputError(f"{path.name}, line {number}: ITEM: {kind} without its "
                                         "TIMESTEP and NUMBER OF lines")
                    columns = item.split()[1:]
                    block = list(itertools.islice(lines, rows))
                    number += len(block)
                    yield DumpFrame(path, step, time, columns, _table(block, rows, columns, path, step))
                    step, time, rows = None, math.nan, None
                else:
                    raise InputError(f"{path.name}, line {number}: unknown item {text!r}: not a LAMMPS "
                                     "dump custom or dump local text file")
            except InputError:
                raise
            except StopIteration:
                raise InputError(f"{path.name}: the file ends inside ITEM: {item} (cut short?)") from None
            except (ValueError, IndexError):
                raise InputError(f"{path.name}, line {number}: ITEM: {item} is not followed by a "
                                 "number") from None


def _table(block: list, rows: int, columns: list, path: Path, step: int) -> np.ndarray:
    where = f"{path.name}, step {step}"
    if len(block) < rows:
        raise InputError(f"{where}: the frame is cut short: {len(block)} of its {rows} rows "
                         "(a run stopped while writing?)")
    ncol = len(columns)
    tokens = " ".join(block).split()
    if len(tokens) != rows * ncol:
        for k, line in enumerate(block):
            if len(line.split()) != ncol:
                raise InputError(f"{where}: row {k} has {len(line.split())} values, the frame "
                                 f"{ncol} columns ({' '.join(columns)})")
    try:
        return np.array(tokens, dtype=np.float64).reshape(rows, ncol)
    except ValueError:
        for k, line in enumerate(block):
            for name, tok in zip(columns, line.split()):
                try:
                    float(tok)
                except ValueError:
                    raise InputError(f"{where}: column {name}, row {k} holds {tok!r}, not a "
                                     "number") from None
        raise


def _first_step(path: Path) -> int:
    """The first timestep of a dump file (its header only is read)."""
    try:
        with _open(path) as fh:
            for line in fh:
                if line.strip() == "ITEM: TIMESTEP":
                    try:
                        return int(fh.readline().split()[0])
                    except (ValueError, IndexError):
                        break
    except (OSError, EOFError) as e:
        raise InputError(f"{path.name}: cannot be read ({' '.join(str(e).split())})") from None
    raise InputError(f"{path.name}: no ITEM: TIMESTEP followed by a number (empty, or not a "
                     "LAMMPS dump)")


def frames_in_order(paths, kind: str):
    """The frames of the dump files ``paths``, files taken in the order of their first timestep;
    InputError when a timestep does not increase (within a file or across files)."""
    paths = sorted((Path(p) for p in paths), key=lambda p: (_first_step(p), str(p)))
    last = None
    for path in paths:
        for frame in dump_frames(path, kind):
            if last is not None and frame.step <= last.step:
                raise InputError(f"{frame.where}: frames out of order: timestep {frame.step} "
                                 f"follows timestep {last.step} ({last.path.name})")
            last = frame
            yield frame


def read_angles(path: Path) -> dict:
    """``--angles FILE``: a CSV with a header, columns step and theta_deg (or step, gx, gy) ->
    {step: theta_deg}."""
    import pandas as pd

    path = Path(path)
    try:
        table = pd.read_csv(path, skipinitialspace=True, comment="#")
    except (OSError, ValueError) as e:
        raise InputError(f"--angles {path}: cannot be read as CSV ({' '.join(str(e).split())})") from None
    cols = set(table.columns)
    where = f"--angles {path.name}"
    if "step" not in cols or not ({"theta_deg"} <= cols or {"gx", "gy"} <= cols):
        raise InputError(f"{where}: needs the columns step and theta_deg (or step, gx and gy); it "
                         f"has {', '.join(map(str, table.columns))}")
    steps = integers(table["step"].to_numpy(), "step", where)
    if "theta_deg" in cols:
        theta = finite(table["theta_deg"].to_numpy(), "theta_deg", where)
    else:
        gx = finite(table["gx"].to_numpy(), "gx", where)
        gy = finite(table["gy"].to_numpy(), "gy", where)
        theta = np.degrees(np.arctan2(gx, -gy))
    if np.unique(steps).size != steps.size:
        raise InputError(f"{where}: step {int(steps[np.flatnonzero(np.diff(np.sort(steps)) == 0)[0]])} "
                         "appears twice")
    return dict(zip(steps.tolist(), theta.tolist()))


def _per_atom_constant(values: np.ndarray, field: str, where: str) -> float:
    v = finite(values, field, where)
    if v.size == 0:
        raise InputError(f"{where}: no atoms to read {field} from")
    if np.ptp(v) > 1e-12 * (1.0 + np.abs(v).max()):
        raise InputError(f"{where}: {field} differs between atoms ({float(v.min())!r} to {float(v.max())!r}): it "
                         "is one value per frame")
    return float(v[0])


class LammpsReader:
    """The raw frames of LAMMPS dumps (module docstring); iterate it (again for a second pass)."""

    def __init__(self, atoms, contacts, *, box_length: float, atom_columns: str | None = None,
                 contact_columns: str | None = None, fixed_types=(), walls=(), angles=None,
                 timestep: float | None = None):
        self.atoms, self.contacts = [Path(p) for p in atoms], [Path(p) for p in contacts]
        if not self.atoms:
            raise InputError("give the atom dumps (dump custom) to import")
        if not self.contacts:
            raise InputError("--contacts: give the contact dumps (dump local of compute "
                             "property/local patom1 patom2 and compute pair/local)")
        for p in self.atoms + self.contacts:
            if not p.is_file():
                raise InputError(f"{p}: no such file")
        self.box_length = float(box_length)
        self.amap = parse_mapping(atom_columns, tuple(ATOM_ROLES), "--atom-columns")
        self.cmap = parse_mapping(contact_columns, CONTACT_ROLES, "--contact-columns")
        need = [r for r in ("id1", "id2", "fn") if r not in self.cmap]
        if need or not ("ft" in self.cmap or {"ftx", "fty"} <= set(self.cmap.keys())):
            raise InputError("--contact-columns: map id1, id2, fn and ft (or ftx and fty) to the "
                             "contact dump's columns, e.g. id1=c_pa[1],id2=c_pa[2],fn=c_pl[1],"
                             "ftx=c_pl[2],fty=c_pl[3]")
        if "ft" in self.cmap and ({"ftx", "fty"} & set(self.cmap)):
            raise InputError("--contact-columns: give ft (signed) or ftx and fty, not both")
        if ("ftx" in self.cmap) != ("fty" in self.cmap):
            raise InputError("--contact-columns: give both ftx and fty")
        if "radius" in self.amap and "diameter" in self.amap:
            raise InputError("--atom-columns: give radius or diameter, not both")
        if ("gx" in self.amap) != ("gy" in self.amap):
            raise InputError("--atom-columns: give both gx and gy (the gravity vector)")
        if "theta" in self.amap and "gx" in self.amap:
            raise InputError("--atom-columns: give theta or gx and gy, not both")
        in_atoms = "theta" in self.amap or "gx" in self.amap
        if angles is not None and in_atoms:
            raise InputError("give the tilt angle once: --angles or --atom-columns theta / gx,gy")
        if angles is None and not in_atoms:
            raise InputError("give the tilt angle of each frame: --angles FILE.csv (step, "
                             "theta_deg), or a per-atom column, --atom-columns theta=COLUMN or "
                             "gx=COLUMN,gy=COLUMN (the gravity vector)")
        self.angles = read_angles(angles) if angles is not None else None
        try:
            self.fixed_types = {int(t) for t in fixed_types}
        except (TypeError, ValueError):
            raise InputError(f"--fixed-types: atom types are integers, got {fixed_types!r}") from None
        self.walls = parse_walls(walls)
        if timestep is not None and not (math.isfinite(timestep) and timestep > 0):
            raise InputError(f"--timestep must be a positive number, got {timestep!r}")
        self.timestep = timestep

    def describe(self) -> dict:
        """What the run file's /import group records of the source."""
        return {"format": "lammps", "atoms": [p.name for p in self.atoms],
                "contacts": [p.name for p in self.contacts],
                "atom_columns": self.amap, "contact_columns": self.cmap,
                "fixed_types": sorted(self.fixed_types), "walls": self.walls,
                "angles": "per-atom column" if self.angles is None else "--angles file"}

    def __iter__(self):
        contacts = frames_in_order(self.contacts, "ENTRIES")
        pending = next(contacts, None)
        for k, atoms in enumerate(frames_in_order(self.atoms, "ATOMS")):
            while pending is not None and pending.step < atoms.step:
                pending = next(contacts, None)
            if pending is None or pending.step != atoms.step:
                raise InputError(f"{label(k, atoms.step, atoms.path.name)}: no contact frame at "
                                 f"timestep {atoms.step} in the contact dumps (--contacts)")
            yield self._frame(atoms, pending, k)

    # -- one frame --------------------------------------------------------------------------
    def _atom(self, frame: DumpFrame, role: str, required: bool) -> np.ndarray | None:
        name = self.amap.get(role, ATOM_ROLES[role])
        if name is None:
            return None
        if name not in frame.columns and not required and role not in self.amap:
            return None
        return frame.column(name, role, "--atom-columns")

    def _frame(self, atoms: DumpFrame, cont: DumpFrame, k: int) -> RawFrame:
        where = label(k, atoms.step, atoms.path.name)
        ids = integers(self._atom(atoms, "id", True), "id", where)
        x, y = self._atom(atoms, "x", True), self._atom(atoms, "y", True)
        if "diameter" in self.amap or ("radius" not in self.amap and "radius" not in atoms.columns
                                       and "diameter" in atoms.columns):
            radius = 0.5 * self._atom(atoms, "diameter", True)
        else:
            radius = self._atom(atoms, "radius", True)
        if self.fixed_types:
            types = integers(self._atom(atoms, "type", True), "type", where)
            fixed = np.isin(types, sorted(self.fixed_types))
        else:
            fixed = np.zeros(ids.size, bool)
        vx, vy = self._atom(atoms, "vx", False), self._atom(atoms, "vy", False)
        if (vx is None) != (vy is None):
            raise InputError(f"{where}: vx without vy (or the reverse): give both velocity columns")
        velocity = None if vx is None else np.column_stack([vx, vy])
        omega = self._atom(atoms, "omega", False)
        position = np.column_stack([x, y])   # NaN: the converter names it
        theta = self._theta(atoms, where)
        time = atoms.time
        if self.timestep is not None:
            time = atoms.step * self.timestep
        id1, id2, fn, ft, sliding = self._pairs(cont, ids, position, label(k, cont.step, cont.path.name))
        w1, w2, wfn, wft = self._walls(atoms, ids, position, where)
        return RawFrame(
            where=f"{atoms.path.name} + {cont.path.name}", step=atoms.step, time=time,
            theta_deg=theta, id=ids, position=position, radius=radius, fixed=fixed,
            velocity=velocity, omega=omega, rotation=None,
            id1=np.concatenate([id1, w1]), id2=np.concatenate([id2, w2]),
            fn=np.concatenate([fn, wfn]), ft=np.concatenate([ft, wft]),
            sliding=None if sliding is None else np.concatenate([sliding, np.zeros(w1.size, bool)]))

    def _theta(self, atoms: DumpFrame, where: str) -> float:
        if self.angles is not None:
            if atoms.step not in self.angles:
                raise InputError(f"{where}: --angles has no row for step {atoms.step}")
            return float(self.angles[atoms.step])
        if "theta" in self.amap:
            return _per_atom_constant(self._atom(atoms, "theta", True), "theta", where)
        gx = _per_atom_constant(self._atom(atoms, "gx", True), "gx", where)
        gy = _per_atom_constant(self._atom(atoms, "gy", True), "gy", where)
        return math.degrees(math.atan2(gx, -gy))

    def _pairs(self, cont: DumpFrame, ids: np.ndarray, position: np.ndarray, where: str):
        m = self.cmap
        col = {role: cont.column(name, role, "--contact-columns") for role, name in m.items()}
        id1 = integers(col["id1"], "contact id1", where)
        id2 = integers(col["id2"], "contact id2", where)
        fn = finite(col["fn"], "contact fn", where, what="contact")
        sliding = None if "sliding" not in col else flags(col["sliding"], "contact sliding", where)
        if "ft" in col:
            return id1, id2, fn, finite(col["ft"], "contact ft", where, what="contact"), sliding
        # the tangential force on atom 1 along t = (-n_y, n_x), n from atom 2 to atom 1 (as the
        # DEM engine reads it: swap-invariant)
        order = np.argsort(ids, kind="stable")
        sid = ids[order]
        rows = []
        for side, a in (("id1", id1), ("id2", id2)):
            k = np.minimum(np.searchsorted(sid, a), max(sid.size - 1, 0))
            if a.size and (sid.size == 0 or (sid[k] != a).any()):
                bad = a[sid[k] != a][0] if sid.size else a[0]
                raise InputError(f"{where}: contact {side} {int(bad)} is no atom of the frame")
            rows.append(order[k] if a.size else k)
        d = position[rows[0]] - position[rows[1]]
        dist = np.hypot(d[:, 0], d[:, 1])
        if (dist == 0).any():
            raise InputError(f"{where}: atoms {int(id1[dist == 0][0])} and {int(id2[dist == 0][0])} "
                             "of a contact sit at the same place")
        nrm = d / dist[:, None]
        tan = np.column_stack([-nrm[:, 1], nrm[:, 0]])
        f = np.column_stack([finite(col["ftx"], "contact ftx", where, what="contact"),
                             finite(col["fty"], "contact fty", where, what="contact")])
        return id1, id2, fn, np.einsum("ij,ij->i", f, tan), sliding

    def _walls(self, atoms: DumpFrame, ids: np.ndarray, position: np.ndarray, where: str):
        """Contacts with the planes of ``fix wall/gran ... contacts`` (per atom: flag, fx, fy)."""
        out = [[], [], [], []]
        L = self.box_length
        for name, plane in self.walls.items():
            cols = [atoms.column(f"{name}[{c}]", f"--wall {name}={plane}", "--wall") for c in (1, 2, 3)]
            flag = finite(cols[0], f"{name}[1]", where, ids, what="atom id")
            fx = finite(cols[1], f"{name}[2]", where, ids, what="atom id")
            fy = finite(cols[2], f"{name}[3]", where, ids, what="atom id")
            k = np.flatnonzero(flag > 0.5)
            x = position[k, 0]
            if plane == "floor":
                wall, fn, ft = np.full(k.size, WALL_IDS["floor"]), fy[k], -fx[k]
            else:
                left = np.full(k.size, plane == "left") if plane != "sides" else x < 0.5 * L
                wall = np.where(left, WALL_IDS["left"], WALL_IDS["right"])
                fn, ft = np.where(left, fx[k], -fx[k]), np.where(left, fy[k], -fy[k])
            for lst, v in zip(out, (ids[k], wall, fn, ft)):
                lst.append(v)
        return tuple(np.concatenate(v) if v else np.zeros(0) for v in out)
