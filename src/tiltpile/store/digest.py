"""The SHA-256 digests of a run file: over its attributes (root attr ``attrs_sha256``, which
``verify`` checks) and over its frames as stored (a checkpoint's ``frames_digest``), computed the
same way by the writer and the reader."""

from __future__ import annotations

import hashlib

import h5py
import numpy as np

from tiltpile.store.layout import ATTRS_DIGEST, CONTACT_SETS, FRAME_ARRAYS, FRAME_SCALARS


def _attrs_digest(f) -> str:
    """SHA-256 over the attributes of the root and the groups (configuration, seed, deposition,
    health, ...; names sorted), as read back from the file: metadata, which the datasets'
    checksums do not cover. (The datasets' ``units`` and ``description`` are checked against
    ``LAYOUT`` instead.)"""
    h = hashlib.sha256()
    objects = [("/", f)]
    f.visititems(lambda name, obj: objects.append((name, obj)) if isinstance(obj, h5py.Group) else None)
    for path, obj in sorted(objects, key=lambda t: t[0]):
        for key in sorted(obj.attrs):
            if path == "/" and key == ATTRS_DIGEST:
                continue
            v = obj.attrs[key]
            h.update(f"{path}\0{key}\0".encode())
            if isinstance(v, (str, bytes)):
                h.update(v.encode() if isinstance(v, str) else v)
            else:
                a = np.asarray(v)
                if a.dtype.kind in "OUS":
                    h.update(repr(a.tolist()).encode())
                else:
                    h.update(f"{a.dtype.str}{a.shape}".encode() + a.tobytes())
    return h.hexdigest()
def _digest_frame(h, get) -> None:
    """Feed one frame, as stored (dataset dtypes), to the hash ``h`` in a fixed order;
    ``get(name)`` gives its value for each name of FRAME_SCALARS, FRAME_ARRAYS and CONTACT_SETS."""
    for name, dt in FRAME_SCALARS.items():
        h.update(np.asarray(get(name), dt).tobytes())
    for name in FRAME_ARRAYS:
        h.update(np.ascontiguousarray(get(name), np.float64).tobytes())
    h.update(np.int64(get("pair").shape[0]).tobytes())
    for name, (dt, _) in CONTACT_SETS.items():
        h.update(np.ascontiguousarray(get(name), dt).tobytes())
