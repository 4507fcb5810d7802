"""The frame log: what ``NAME.part`` holds while a run is written (the package docstring says
why). An append-only file of records; bytes once written are never rewritten, so a process
killed at any moment leaves every record before the one it was writing intact, and the
checkpoint (``NAME.ckpt``, attr ``log_bytes``) names the length up to which the log is whole.

Format (all integers little-endian)::

    MAGIC (16 bytes)
    record*:  kind (4 bytes ASCII)  length (uint64)  payload (length bytes)

Kinds, in the order the writer appends them:

- ``HEAD`` (once, first): uint64 J, J bytes of JSON ``{"n": N, "attrs": [[key, value], ...]}``
  (the run file's first root attributes, in order: version, seed, configuration, ...), then
  ``particles/radius`` (N float64) and ``particles/fixed`` (N bool).
- ``ATTR``: JSON ``{"group": "/" or a group name, "attrs": [[key, value], ...]}``, a value a
  JSON string or ``{"dtype": ..., "shape": [...], "hex": ...}`` (the exact NumPy value).
- ``FRAM``: one frame, exactly the bytes ``digest._digest_frame`` feeds the frames digest:
  the scalars of ``FRAME_SCALARS`` (8 bytes each, their dtypes), position (N, 2), velocity
  (N, 2), rotation (N,), omega (N,) as float64, the contact count M (int64), then pair (M, 2)
  int32, force (M, 2) float64, status (M,) int8. The SHA-256 over the FRAM payloads, in order,
  is the checkpoint's ``frames_digest``.
- ``SYNC``: empty; a checkpoint was written here (the run file built from the log is flushed at
  the same places, so that it is the file the writer wrote before the log existed, byte for byte).
- ``DONE``: the ``attrs_sha256`` (64 ASCII hex) of the run file built from the records before
  it: appended, synced, just before that file is renamed to ``NAME``.
"""

from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tiltpile.store.layout import CONTACT_SETS, FRAME_ARRAYS, FRAME_SCALARS

MAGIC = b"TILTPILE-FRAMES1"
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_REC = struct.Struct("<4sQ")
_SCALARS = struct.calcsize("<" + "q" * len(FRAME_SCALARS))  # every scalar column has 8 bytes
_ARRAY_COLS = {"position": 2, "velocity": 2, "rotation": 1, "omega": 1}  # float64 per grain


class LogError(ValueError):
    """A frame log that does not hold what its checkpoint says (the message says how)."""


def is_frame_log(path: Path) -> bool:
    """Whether ``path`` starts as a frame log (else, e.g., a ``.part`` an older writer wrote as HDF5)."""
    try:
        with open(path, "rb") as fh:
            return fh.read(len(MAGIC)) == MAGIC
    except OSError:
        return False


def encode_value(v):
    """An attribute value as JSON: strings as such, anything else as its exact NumPy bytes."""
    if isinstance(v, str):
        return v
    a = np.asarray(v)
    if a.dtype.kind in "OUS":
        raise TypeError(f"attribute value {v!r} cannot be logged")
    return {"dtype": a.dtype.str, "shape": list(a.shape), "hex": a.tobytes().hex()}


def decode_value(v):
    if isinstance(v, str):
        return v
    a = np.frombuffer(bytes.fromhex(v["hex"]), dtype=np.dtype(v["dtype"])).reshape(v["shape"])
    return a[()] if a.ndim == 0 else a.copy()


def frame_payload(frame) -> list:
    """The FRAM payload of a ``protocol.Frame`` as a list of buffers (``_digest_frame``'s order)."""
    parts = [np.asarray(getattr(frame, name), dt).tobytes() for name, dt in FRAME_SCALARS.items()]
    parts += [np.ascontiguousarray(getattr(frame, name), np.float64) for name in FRAME_ARRAYS]
    pair = np.ascontiguousarray(frame.pair, np.int32)
    parts.append(np.int64(pair.shape[0]).tobytes())
    for name, (dt, _) in CONTACT_SETS.items():
        parts.append(np.ascontiguousarray(getattr(frame, name), dt))
    return [memoryview(p).cast("B") if isinstance(p, np.ndarray) else p for p in parts]


def parse_frame(payload: memoryview, n: int) -> dict:
    """A FRAM payload as ``{name: value}`` (scalars as NumPy scalars, arrays as read-only views)."""
    out, at = {}, 0
    for name, dt in FRAME_SCALARS.items():
        out[name] = np.frombuffer(payload, dt, 1, at)[0]
        at += 8
    for name in FRAME_ARRAYS:
        cols = _ARRAY_COLS[name]
        a = np.frombuffer(payload, np.float64, n * cols, at)
        out[name] = a.reshape((n, 2)) if cols == 2 else a
        at += 8 * n * cols
    m = int(np.frombuffer(payload, np.int64, 1, at)[0])
    at += 8
    for name, (dt, shape) in CONTACT_SETS.items():
        size = int(np.prod(shape, dtype=np.int64))
        a = np.frombuffer(payload, dt, m * size, at)
        out[name] = a.reshape((m, *shape))
        at += a.nbytes
    if at != len(payload):
        raise LogError(f"a frame record of {len(payload)} bytes holds {at}")
    return out


def head_payload(attrs: list, radius: np.ndarray, fixed: np.ndarray) -> bytes:
    text = json.dumps({"n": int(radius.shape[0]), "attrs": [[k, encode_value(v)] for k, v in attrs]}).encode()
    return (struct.pack("<Q", len(text)) + text + np.ascontiguousarray(radius, np.float64).tobytes()
            + np.ascontiguousarray(fixed, np.bool_).tobytes())


def attr_payload(group: str, items: list) -> bytes:
    return json.dumps({"group": group, "attrs": [[k, encode_value(v)] for k, v in items]}).encode()


@dataclass
class Head:
    n: int
    attrs: list  # [(key, value)], the run file's first root attributes in order
    radius: np.ndarray
    fixed: np.ndarray


def parse_head(payload) -> Head:
    (j,) = struct.unpack_from("<Q", payload, 0)
    meta = json.loads(bytes(payload[8:8 + j]))
    n = int(meta["n"])
    at = 8 + j
    radius = np.frombuffer(payload, np.float64, n, at).copy()
    fixed = np.frombuffer(payload, np.bool_, n, at + 8 * n).copy()
    if at + 9 * n != len(payload):
        raise LogError("its head record has the wrong size")
    return Head(n, [(k, decode_value(v)) for k, v in meta["attrs"]], radius, fixed)


def parse_attrs(payload) -> tuple[str, list]:
    meta = json.loads(bytes(payload))
    return meta["group"], [(k, decode_value(v)) for k, v in meta["attrs"]]


def read_records(path: Path, end: int | None = None):
    """(kind, payload, offset after the record) of every record of the log at ``path`` up to
    byte ``end``; ``LogError`` if the file is not a log, is shorter than ``end`` or ``end`` does
    not fall on a record's end. With ``end`` None: every whole record (a torn last one is left out)."""
    with open(path, "rb") as fh:
        if fh.read(len(MAGIC)) != MAGIC:
            raise LogError("it is not a frame log")
        size = os.fstat(fh.fileno()).st_size
        if end is not None and end > size:
            raise LogError(f"it holds {size} bytes, fewer than the {end} its checkpoint follows")
        stop = size if end is None else end
        at = len(MAGIC)
        while at < stop:
            if at + _REC.size <= stop:
                kind, length = _REC.unpack(fh.read(_REC.size))
                if at + _REC.size + length <= stop:
                    payload = fh.read(length)
                    at += _REC.size + length
                    yield kind, memoryview(payload), at
                    continue
            if end is None:
                return
            raise LogError("its checkpoint ends inside a record")


def last_record(path: Path) -> tuple[bytes, bytes] | None:
    """(kind, payload) of the log's last whole record when it is a short one (``DONE``), else None."""
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            n = _REC.size + 64
            if size < len(MAGIC) + n or fh.read(len(MAGIC)) != MAGIC:
                return None
            fh.seek(size - n)
            kind, length = _REC.unpack(fh.read(_REC.size))
            return (kind, fh.read(64)) if length == 64 else None
    except OSError:
        return None


class LogWriter:
    """Appends records to a frame log through one file descriptor (unbuffered: each record is
    handed to the kernel whole or, if the process dies inside the call, in part, past the end
    the next checkpoint names)."""

    def __init__(self, path: Path, fd: int, size: int):
        self.path, self.fd, self.size = Path(path), fd, int(size)

    @classmethod
    def create(cls, path: Path) -> LogWriter:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        w = cls(path, fd, 0)
        try:
            w._write([MAGIC])
        except BaseException:
            w.close()
            raise
        return w

    @classmethod
    def reopen(cls, path: Path, size: int) -> LogWriter:
        """Open ``path`` for appending after its first ``size`` bytes (the rest is cut off)."""
        fd = os.open(path, os.O_WRONLY)
        try:
            os.ftruncate(fd, size)
        except BaseException:
            os.close(fd)
            raise
        return cls(path, fd, size)

    def _write(self, buffers: list) -> None:
        total = sum(len(b) for b in buffers)
        done = os.pwritev(self.fd, buffers, self.size)
        if done < total:  # a short write (a full disk reports the rest as an OSError)
            rest = b"".join(bytes(b) for b in buffers)[done:]
            while rest:
                n = os.pwrite(self.fd, rest, self.size + done)
                if n <= 0:
                    raise OSError(28, "No space left on device")
                done, rest = done + n, rest[n:]
        self.size += total

    def record(self, kind: bytes, buffers: list) -> None:
        length = sum(len(b) for b in buffers)
        self._write([_REC.pack(kind, length), *buffers])

    def sync(self) -> None:
        os.fsync(self.fd)

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


CONTACT_BYTES = 25  # pair (2 int32), force (2 float64), status (int8)


def frame_nbytes(n: int, m: int) -> int:
    """Bytes of the FRAM record (header included) of a frame of ``n`` grains and ``m`` contacts."""
    return _REC.size + _SCALARS + 48 * n + 8 + CONTACT_BYTES * m


def read_columns(path: Path) -> tuple[dict, np.ndarray]:
    """(per-frame scalar columns of every whole frame record, ``particles/fixed``) of the log at
    ``path``: what an interrupted run wrote (its frames past the checkpoint included)."""
    columns: dict = {name: [] for name in FRAME_SCALARS}
    head = None
    for kind, payload, _ in read_records(path):
        if kind == b"HEAD":
            head = parse_head(payload)
        elif kind == b"FRAM":
            fr = parse_frame(payload, head.n)
            for name in FRAME_SCALARS:
                columns[name].append(fr[name])
    if head is None:
        raise LogError("it has no head record")
    return {k: np.array(v, FRAME_SCALARS[k]) for k, v in columns.items()}, head.fixed
