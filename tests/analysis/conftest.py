"""Hand-built contact networks and tiny run files with known observables (factory fixtures)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

SQ3 = np.sqrt(3.0)


def geometric_contacts(position, radius, box_length, tol=1e-9):
    """All touching pairs (|x_i - x_j| <= r_i + r_j + tol) and wall contacts, brute force.

    Returns pair (C, 2) int32 with i < j for grains and j in {-1, -2, -3} for walls.
    """
    position = np.asarray(position, float)
    radius = np.asarray(radius, float)
    n = len(radius)
    pairs = []
    for i in range(n):
        x, y = position[i]
        r = radius[i]
        if y - r <= tol:
            pairs.append((i, -1))
        if x - r <= tol:
            pairs.append((i, -2))
        if box_length - x - r <= tol:
            pairs.append((i, -3))
        for j in range(i + 1, n):
            if np.hypot(*(position[j] - position[i])) <= r + radius[j] + tol:
                pairs.append((i, j))
    return np.array(pairs, dtype=np.int32).reshape(-1, 2)


def triangular_pile(width: int, rows: int):
    """A triangular packing of unit disks on a fixed bottom row, in a box of length ``width``.

    Row 0 (fixed): ``width`` grains at x = 0.5, 1.5, ..., y = 0.5. Row q >= 1 at
    y = 0.5 + q sqrt(3)/2: odd rows have width - 1 grains at x = 1, 2, ..., even rows ``width``
    grains at x = 0.5, ... (touching the side walls). ``rows`` mobile rows; make it even so the top
    row is a full one (then it alone is the top layer). Returns position (N, 2), radius (N,),
    fixed (N,) bool, row (N,) int.
    """
    pos, row = [], []
    for q in range(rows + 1):
        y = 0.5 + q * SQ3 / 2
        xs = np.arange(1, width) if q % 2 else np.arange(width) + 0.5
        pos += [(x, y) for x in xs]
        row += [q] * len(xs)
    pos = np.array(pos, float)
    row = np.array(row)
    return pos, np.full(len(pos), 0.5), row == 0, row


@pytest.fixture
def pile_factory():
    return triangular_pile


@pytest.fixture
def contacts_factory():
    return geometric_contacts


def write_run(path, radius, fixed, box_length, positions, contacts, theta_deg, velocities=None,
              omegas=None, seed=7, mu=0.5):
    """Write a minimal run file in the store's HDF5 layout (see tiltpile.store).

    positions: list of (N, 2) per frame; contacts: list of (pair, force, status) per frame.
    """
    from tiltpile.store import FRAME_SCALARS

    nf = len(positions)
    n = len(radius)
    velocities = velocities if velocities is not None else [np.zeros((n, 2))] * nf
    omegas = omegas if omegas is not None else [np.zeros(n)] * nf
    with h5py.File(path, "w") as f:
        f.attrs["tiltpile_version"] = "test"
        f.attrs["seed"] = seed
        f.attrs["config"] = json.dumps({"scene": {"mu": mu, "mu_wall": mu}, "solver": {}, "protocol": {}})
        f.attrs["config_hash"] = "test"
        f.attrs["box_length"] = float(box_length)
        f.attrs["complete"] = True
        f["particles/radius"] = np.asarray(radius, float)
        f["particles/fixed"] = np.asarray(fixed, bool)
        scal = {"step": np.arange(nf) * 50, "time": np.arange(nf) * 0.5,
                "theta_deg": np.asarray(theta_deg, float), "iterations": np.full(nf, 10),
                "residual": np.full(nf, 1e-5)}
        for name, dt in FRAME_SCALARS.items():
            f[f"frames/{name}"] = np.asarray(scal.get(name, np.zeros(nf)), dtype=dt)
        f["frames/position"] = np.stack(positions)
        f["frames/rotation"] = np.zeros((nf, n))
        f["frames/velocity"] = np.stack(velocities)
        f["frames/omega"] = np.stack(omegas)
        counts = [len(c[0]) for c in contacts]
        f["contacts/offset"] = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        f["contacts/pair"] = np.concatenate([c[0] for c in contacts]).astype(np.int32).reshape(-1, 2)
        f["contacts/force"] = np.concatenate([c[1] for c in contacts]).astype(float).reshape(-1, 2)
        f["contacts/status"] = np.concatenate([c[2] for c in contacts]).astype(np.int8)


@pytest.fixture
def run_writer():
    return write_run
