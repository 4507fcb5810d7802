"""Grains, box and walls.

A scene is plain arrays:

``radius``   (N,) float64, grain radii [d]; diameters uniform in [1 - p, 1 + p] with p the
             polydispersity (p = 0.2: 20 % polydispersity as the half-width of the diameter range
             relative to the mean d = 1; the paper's "20 % polydispersity", Henkes et al. 2010).
``fixed``    (N,) bool, the grains of the rough bottom: one row of touching grains of the same size
             distribution resting on the floor, held fixed (infinite mass).
``position`` (N, 2) float64 [d], box frame: x along the floor, y up from the floor.
``inv_mass`` (N,) float64 [1/m]; mass = disk area (density 1), 0 for fixed grains.

Ids: fixed grains first (0..n_fixed-1, left to right), then mobile grains bottom-up in the loose
initial lattice, so contact lists sorted by particle id are roughly sorted by height.

Walls are virtual bodies with ids -1 (floor, y = 0, normal +y), -2 (left wall, x = 0, normal +x)
and -3 (right wall, x = L, normal -x). Kernels index them as N + 0, N + 1, N + 2 in the velocity
array (zero velocity, zero inverse mass).

Disk inertia I = m r^2 / 2. Kernels carry the rim speed s = r * omega instead of omega, so the
contact algebra needs only 1/m: a tangential impulse p_t changes s by -2 p_t / m.
"""

from __future__ import annotations

import numpy as np

FLOOR, LEFT, RIGHT = -1, -2, -3
N_WALLS = 3


def diameters(n: int, polydispersity: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` diameters uniform in [1 - p, 1 + p]."""
    return rng.uniform(1.0 - polydispersity, 1.0 + polydispersity, size=n)


def make_scene(n: int, polydispersity: float, box_length: float, fill_spacing: float,
               rng: np.random.Generator) -> dict[str, np.ndarray]:
    """A box of length ``box_length`` with a fixed rough bottom row and ``n`` mobile grains.

    Mobile grains sit on a square lattice of spacing ``fill_spacing * d_max`` above the bottom
    row, each displaced at random by up to half the free space, so none overlap; they then fall
    under gravity (deposition). Returns radius, fixed, position, inv_mass (see module doc).
    """
    d_max = 1.0 + polydispersity
    # Rough bottom: touching grains resting on the floor, left to right, the last one kept only
    # if its centre is inside the box (it may overlap the right wall: fixed bodies do not interact).
    fixed_d = []
    x = 0.0
    while True:
        d = diameters(1, polydispersity, rng)[0]
        if x + d / 2 > box_length:
            break
        fixed_d.append(d)
        x += d
    fixed_d = np.array(fixed_d)
    fixed_x = np.cumsum(fixed_d) - fixed_d / 2
    fixed_pos = np.column_stack([fixed_x, fixed_d / 2])

    mobile_d = diameters(n, polydispersity, rng)
    a = fill_spacing * d_max
    ncol = max(1, int((box_length - (a - d_max)) // a))
    row = np.arange(n) // ncol
    col = np.arange(n) % ncol
    free = a - mobile_d  # room for jitter in each lattice cell
    jitter = (rng.random((n, 2)) - 0.5) * free[:, None]
    x0 = (box_length - ncol * a) / 2 + a / 2
    y0 = 2 * d_max + a / 2
    mobile_pos = np.column_stack([x0 + col * a, y0 + row * a]) + jitter

    radius = np.concatenate([fixed_d, mobile_d]) / 2
    fixed = np.zeros(radius.size, dtype=bool)
    fixed[: fixed_d.size] = True
    position = np.concatenate([fixed_pos, mobile_pos])
    inv_mass = np.where(fixed, 0.0, 1.0 / (np.pi * radius**2))
    return dict(radius=radius, fixed=fixed, position=np.ascontiguousarray(position), inv_mass=inv_mass)


def gravity(theta_deg: float) -> np.ndarray:
    """Gravity (g = 1) in the box frame when the box is tilted by ``theta_deg``: (sin, -cos)."""
    t = np.deg2rad(theta_deg)
    return np.array([np.sin(t), -np.cos(t)])
