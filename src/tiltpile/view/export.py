"""Export a run to the particle and mesh viewers of the field: extended XYZ and VTK XML.

Both formats carry, per frame and per grain, the stored state (position with z = 0, radius,
velocity, omega, fixed, id) and the derived fields of :mod:`tiltpile.view.fields` (n_active,
n_mobilized, cluster, failing, failing_next); the VTK export adds the contacts as lines.

Extended XYZ (:func:`write_extxyz`; OVITO, ASE, VMD read it) -- one multi-frame text file::

    N
    Lattice="L 0 0 0 H 0 0 0 1" Properties=species:S:1:pos:R:3:radius:R:1:velo:R:3:omega:R:1:...
        frame=k step=... time=... theta_deg=... box_length=L gravity="gx gy 0" pbc="F F F"
    X  x y 0  r  vx vy 0  omega  fixed  id  n_active  n_mobilized  cluster  failing  failing_next

Every grain is species ``X`` (ASE's dummy element); the cell is the box: length L along x and a
height H, the highest grain top over the exported frames (the box has no lid). Booleans are
``T``/``F``. Written here rather than with ``ase.io.write`` because ASE formats every float as
``%16.8f``, which keeps one or two significant digits of the velocities of a pile at rest
(1e-6 to 1e-4 sqrt(g d)); here floats are written with ``%.10g``. ASE reads the file back
(``ase.io.read(path, index=":")``); the tests do.

VTK XML (:func:`write_vtk`; ParaView, VisIt) -- ``OUT.pvd`` lists, for each frame, two
UnstructuredGrid files in the folder ``OUT/``: ``grains_KKKKK.vtu`` (one point and one vertex
cell per grain, the grain fields as point data) and ``contacts_KKKKK.vtu`` (the contacts of the
frame as line cells between grain centres, or from a centre to the touching point on a wall,
with cell data f_n, f_t, status (0 open, 1 sticking, 2 sliding), active, mobilized, and the pair
i, j (j < 0: wall)). The two are parts 0 and 1 of each time step; the step's time value is the
tilt angle theta in degrees (frame index if theta does not increase). Each file also carries
field data theta_deg, time, step, frame and TimeValue. Arrays are binary, zlib-compressed,
base64-encoded in the XML (``header_type="UInt64"``). Written here (~100 lines against the VTK
file-format spec) because the libraries that write it either cannot write .pvd collections with
parts (meshio) or need the 140 MB ``vtk`` wheel; meshio reads the files back in the tests.

ParaView: open OUT.pvd; grains: representation "Point Gaussian", scale array radius, color by
cluster or failing; force chains: the contacts part, "Threshold" on active, color or "Tube"
radius by f_n.
"""

from __future__ import annotations

import base64
import struct
import time
import zlib
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from tiltpile.store import open_run

from .fields import FrameFields, contact_segments, parse_frames
from .output import progress_frames, replaced_when_complete

FORMATS = ("extxyz", "vtk")


# ----------------------------------------------------------------------------------------------
# extended XYZ

XYZ_COLUMNS = (  # name, extxyz type, components
    ("species", "S", 1), ("pos", "R", 3), ("radius", "R", 1), ("velo", "R", 3), ("omega", "R", 1),
    ("fixed", "L", 1), ("id", "I", 1), ("n_active", "I", 1), ("n_mobilized", "I", 1),
    ("cluster", "I", 1), ("failing", "L", 1), ("failing_next", "L", 1),
)


def _tf(b: np.ndarray) -> np.ndarray:
    return np.where(np.asarray(b, dtype=bool), "T", "F")


def _xyz_frame(f: dict, height: float) -> str:
    """The text of one frame (header, comment line, one line per grain)."""
    n = f["radius"].size
    L = float(f["box_length"])
    height = float(height)
    t = float(np.radians(f["theta_deg"]))
    gx, gy = float(np.sin(t)), -float(np.cos(t))
    props = ":".join(f"{name}:{typ}:{nc}" for name, typ, nc in XYZ_COLUMNS)
    comment = (f'Lattice="{L!r} 0 0 0 {height!r} 0 0 0 1" Properties={props} frame={f["frame"]} '
               f'step={f["step"]} time={f["time"]!r} theta_deg={f["theta_deg"]!r} '
               f'box_length={L!r} gravity="{gx!r} {gy!r} 0" pbc="F F F"')
    p, v = f["position"], f["velocity"]
    cols = [np.full(n, "X"), p[:, 0], p[:, 1], np.zeros(n), f["radius"], v[:, 0], v[:, 1],
            np.zeros(n), f["omega"], _tf(f["fixed"]), np.arange(n), f["n_active"],
            f["n_mobilized"], f["cluster"], _tf(f["failing"]), _tf(f["failing_next"])]
    fmt = "%s %.10g %.10g 0 %.10g %.10g %.10g 0 %.10g %s %d %d %d %d %s %s\n"
    keep = [c for k, c in enumerate(cols) if k not in (3, 7)]  # the literal zeros (z)
    rows = zip(*(c.tolist() for c in keep))
    return f"{n}\n{comment}\n" + "".join(fmt % r for r in rows)


def write_extxyz(run_path, out, frames: str | None = None, progress: bool = True) -> dict:
    """Write the frames ``frames`` (``START:STOP:STEP``) of a run to one extended XYZ file.

    Written to ``out`` + ``.tmp`` and renamed when complete. Returns dict path, frames, bytes,
    seconds.
    """
    t0 = time.perf_counter()
    out = Path(out)
    tmp = out.with_name(out.name + ".tmp")
    with open_run(run_path) as run:
        sel = parse_frames(frames, run.n_frames)
        ff = FrameFields(run)
        r = ff.radius
        height = max(float(np.max(run.position(k)[:, 1] + r)) for k in sel)
        with replaced_when_complete(out, tmp), open(tmp, "w") as fh:
            for k in progress_frames(sel, "extxyz", progress):
                fh.write(_xyz_frame(ff.fields(k), height))
    return {"path": str(out), "frames": len(sel), "bytes": out.stat().st_size,
            "seconds": time.perf_counter() - t0}


# ----------------------------------------------------------------------------------------------
# VTK XML

_VTK_TYPES = {np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32",
              np.dtype(np.int64): "Int64", np.dtype(np.int32): "Int32", np.dtype(np.int8): "Int8",
              np.dtype(np.uint8): "UInt8"}
VTK_VERTEX, VTK_LINE = 1, 3


def _encode(a: np.ndarray, level: int) -> str:
    """Inline binary DataArray body: zlib-compressed in one block, header and data each base64
    (VTK XML format, compressor vtkZLibDataCompressor, header_type UInt64)."""
    raw = np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<"), copy=False).tobytes()
    if not raw:
        header = struct.pack("<3Q", 0, 0, 0)
        return base64.b64encode(header).decode()
    comp = zlib.compress(raw, level)
    header = struct.pack("<4Q", 1, len(raw), len(raw), len(comp))
    return base64.b64encode(header).decode() + base64.b64encode(comp).decode()


def _data_array(name: str | None, a: np.ndarray, level: int, tuples: bool = False) -> str:
    a = np.asarray(a)
    if a.dtype == np.bool_:
        a = a.astype(np.uint8)
    typ = _VTK_TYPES[a.dtype]
    nc = a.shape[1] if a.ndim == 2 else 1
    attrs = f' type="{typ}"'
    if name is not None:
        attrs += f" Name={quoteattr(name)}"
    if nc > 1:
        attrs += f' NumberOfComponents="{nc}"'
    if tuples:
        attrs += f' NumberOfTuples="{a.shape[0]}"'
    return f'<DataArray{attrs} format="binary">{_encode(a, level)}</DataArray>\n'


def _vtu(points: np.ndarray, conn: np.ndarray, offsets: np.ndarray, types: np.ndarray,
         point_data: dict, cell_data: dict, field_data: dict, level: int) -> str:
    parts = ['<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
             'byte_order="LittleEndian" header_type="UInt64" compressor="vtkZLibDataCompressor">\n'
             '<UnstructuredGrid>\n<FieldData>\n']
    parts += [_data_array(k, np.atleast_1d(v), level, tuples=True) for k, v in field_data.items()]
    parts.append(f'</FieldData>\n<Piece NumberOfPoints="{len(points)}" '
                 f'NumberOfCells="{len(types)}">\n<PointData>\n')
    parts += [_data_array(k, v, level) for k, v in point_data.items()]
    parts.append("</PointData>\n<CellData>\n")
    parts += [_data_array(k, v, level) for k, v in cell_data.items()]
    parts.append("</CellData>\n<Points>\n")
    parts.append(_data_array(None, points, level))
    parts.append("</Points>\n<Cells>\n")
    parts.append(_data_array("connectivity", conn.astype(np.int64), level))
    parts.append(_data_array("offsets", offsets.astype(np.int64), level))
    parts.append(_data_array("types", types.astype(np.uint8), level))
    parts.append("</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n")
    return "".join(parts)


def _xyz(p2: np.ndarray) -> np.ndarray:
    return np.column_stack([p2, np.zeros(len(p2))])


def grains_vtu(f: dict, level: int = 6) -> str:
    """The grains of one frame (:meth:`FrameFields.fields`) as a .vtu text."""
    n = f["radius"].size
    v = f["velocity"]
    point_data = {
        "radius": f["radius"], "velocity": _xyz(v), "speed": np.hypot(v[:, 0], v[:, 1]),
        "omega": f["omega"], "fixed": f["fixed"], "id": np.arange(n, dtype=np.int64),
        "n_active": f["n_active"].astype(np.int32), "n_mobilized": f["n_mobilized"].astype(np.int32),
        "cluster": f["cluster"].astype(np.int32), "failing": f["failing"],
        "failing_next": f["failing_next"],
    }
    return _vtu(_xyz(f["position"]), np.arange(n), np.arange(1, n + 1),
                np.full(n, VTK_VERTEX), point_data, {}, _field_data(f), level)


def contacts_vtu(f: dict, level: int = 6) -> str:
    """The contacts of one frame as line cells (.vtu text): points are the grain centres
    followed by one point per wall contact (its touching point on the wall)."""
    n = f["radius"].size
    pair = np.asarray(f["pair"]).reshape(-1, 2)
    c = len(pair)
    wall = pair[:, 1] < 0
    seg = contact_segments(pair, f["position"], f["box_length"])
    points = np.vstack([f["position"], seg[wall, 1]])
    j = pair[:, 1].astype(np.int64).copy()
    j[wall] = n + np.arange(int(wall.sum()))
    conn = np.column_stack([pair[:, 0].astype(np.int64), j]).ravel()
    cell_data = {"f_n": f["force"][:, 0], "f_t": f["force"][:, 1],
                 "status": np.asarray(f["status"], dtype=np.int8), "active": f["active"],
                 "mobilized": f["mobilized"], "i": pair[:, 0].astype(np.int32),
                 "j": pair[:, 1].astype(np.int32)}
    return _vtu(_xyz(points), conn, 2 * np.arange(1, c + 1), np.full(c, VTK_LINE), {}, cell_data,
                _field_data(f), level)


def _field_data(f: dict) -> dict:
    return {"theta_deg": np.float64(f["theta_deg"]), "time": np.float64(f["time"]),
            "TimeValue": np.float64(f.get("time_value", f["theta_deg"])), "step": np.int64(f["step"]),
            "frame": np.int64(f["frame"])}


def write_vtk(run_path, out, frames: str | None = None, progress: bool = True,
              level: int = 6) -> dict:
    """Write the frames of a run as ``OUT.pvd`` and ``OUT/{grains,contacts}_KKKKK.vtu``.

    ``out`` must end in ``.pvd``. The folder's old frame files are replaced; the .pvd is written
    last (to a temporary name, then renamed). Returns dict path, folder, frames, files, bytes
    (all files together), seconds.
    """
    t0 = time.perf_counter()
    out = Path(out)
    if out.suffix != ".pvd":
        raise ValueError(f"{out}: the VTK export is a .pvd collection; give --out NAME.pvd")
    folder = out.with_suffix("")
    folder.mkdir(parents=True, exist_ok=True)
    for old in (*folder.glob("grains_*.vtu"), *folder.glob("contacts_*.vtu")):
        old.unlink()
    entries, nbytes = [], 0
    with open_run(run_path) as run:
        sel = parse_frames(frames, run.n_frames)
        theta = np.asarray(run.theta_deg, dtype=float)[sel]
        use_theta = bool(np.all(np.diff(theta) > 0))
        ff = FrameFields(run)
        for i in progress_frames(range(len(sel)), "vtk", progress):
            k = sel[i]
            f = ff.fields(k)
            tv = float(theta[i]) if use_theta else float(k)
            f["time_value"] = tv
            for part, (name, text) in enumerate((("grains", grains_vtu(f, level)),
                                                 ("contacts", contacts_vtu(f, level)))):
                path = folder / f"{name}_{k:05d}.vtu"
                path.write_text(text)
                nbytes += path.stat().st_size
                entries.append(f'<DataSet timestep="{tv!r}" group="" part="{part}" '
                               f'name="{name}" file="{folder.name}/{path.name}"/>')
    text = ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" '
            'byte_order="LittleEndian">\n<Collection>\n' + "\n".join(entries)
            + "\n</Collection>\n</VTKFile>\n")
    with replaced_when_complete(out, out.with_name(out.name + ".tmp")) as tmp:
        tmp.write_text(text)
    nbytes += out.stat().st_size
    return {"path": str(out), "folder": str(folder), "frames": len(sel), "files": 2 * len(sel) + 1,
            "bytes": nbytes, "seconds": time.perf_counter() - t0}


def export(run_path, out, fmt: str, frames: str | None = None, progress: bool = True) -> dict:
    """Export a run in ``fmt`` ("extxyz" or "vtk"); see :func:`write_extxyz`, :func:`write_vtk`."""
    if fmt == "extxyz":
        return write_extxyz(run_path, out, frames, progress)
    if fmt == "vtk":
        return write_vtk(run_path, out, frames, progress)
    raise ValueError(f"unknown format {fmt!r}; choose from {', '.join(FORMATS)}")
