"""`tiltpile import` (docs/import.md): the plain format round trip on a Contact Dynamics run (NPZ
and CSV), LAMMPS dumps written by hand (the sign conventions of contacts and walls), and each
refusal on small hand-made inputs: one line naming the field and the frame, nothing written.

Tolerance: none. The plain format carries every array the analysis reads, written at full
precision (NPZ: the float64 bytes; CSV: 17 significant digits, which pandas reads back exactly),
so every observable of the imported run equals the simulated run's but the solver's own columns
(iterations, residual), which the format does not carry; the kinetic energy (not an input: the
importer sums it) to 1e-12 relative.
"""

from __future__ import annotations

import gzip
import json
import warnings

import numpy as np
import pytest

from tiltpile import config, store
from tiltpile.cli import main
from tiltpile.importers import Converter, InputError, RawFrame
from tiltpile.importers.plain import CONTACT_FIELDS, FRAME_FIELDS, GRAIN_FIELDS

SOLVER_COLUMNS = ("iterations", "residual")


@pytest.fixture(scope="module")
def cd_run(tmp_path_factory):
    """A 40-grain Contact Dynamics pile tilted to 3 deg (31 frames)."""
    from tiltpile.runner import simulate

    out = tmp_path_factory.mktemp("cd") / "run_0003.h5"
    cfg = config.load("smoke", overrides=["scene.n=40", "scene.box_length=10.0",
                                          "protocol.theta_max_deg=3.0"])
    simulate(cfg, 3, out, progress=False)
    return out


def frames_of(run_path, offset: int = 100) -> list[dict]:
    """Every frame of a run file as plain-format fields (grain ids shifted by ``offset``, so that
    ids are not row numbers; sliding flags from the statuses)."""
    out = []
    with store.open_run(run_path) as r:
        n = r.radius.size
        for k in range(r.n_frames):
            pair, force, status = r.contacts(k)
            pos, vel = r.position(k), r.velocity(k)
            out.append(dict(step=r.step[k], time=r.time[k], theta_deg=r.theta_deg[k],
                            id=np.arange(n) + offset, x=pos[:, 0], y=pos[:, 1], radius=r.radius,
                            fixed=r.fixed, vx=vel[:, 0], vy=vel[:, 1], omega=r.omega(k),
                            rotation=r.rotation(k), id1=pair[:, 0] + offset,
                            id2=np.where(pair[:, 1] >= 0, pair[:, 1] + offset, pair[:, 1]),
                            fn=force[:, 0], ft=force[:, 1], sliding=status == 2))
    return out


def write_npz(frames: list[dict], d):
    d.mkdir(parents=True, exist_ok=True)
    for k, f in enumerate(frames):
        np.savez(d / f"frame_{k}.npz", **f)
    return d


def write_csv(frames: list[dict], d):
    import pandas as pd

    d.mkdir(parents=True, exist_ok=True)
    rows = {"frames": [], "grains": [], "contacts": []}
    for k, f in enumerate(frames):
        rows["frames"].append(pd.DataFrame({"frame": [k], **{c: [f[c]] for c in FRAME_FIELDS if c in f}}))
        rows["grains"].append(pd.DataFrame({"frame": k, **{c: f[c] for c in GRAIN_FIELDS if c in f}}))
        rows["contacts"].append(pd.DataFrame({"frame": k, **{c: f[c] for c in CONTACT_FIELDS if c in f}}))
    for name, parts in rows.items():
        pd.concat(parts).to_csv(d / f"{name}.csv", index=False, float_format="%.17g")
    return d


def _observables(path):
    from tiltpile.analysis.tables import run_observables

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # a 40-grain pile is below the cutoff's resolution
        return run_observables(path)


def _same_tables(a, b, skip=()):
    for x, y in zip(a, b):
        assert list(x.columns) == list(y.columns) and len(x) == len(y)
        for c in x.columns:
            if c not in skip:
                assert np.array_equal(x[c].to_numpy(), y[c].to_numpy(), equal_nan=True), c


@pytest.mark.parametrize("fmt", ["npz", "csv"])
def test_the_plain_format_round_trip_gives_the_same_observables(cd_run, tmp_path, fmt, capsys):
    frames = frames_of(cd_run)
    src = (write_npz if fmt == "npz" else write_csv)(frames, tmp_path / "in")
    out = tmp_path / "mine" / "run_0003.h5"
    assert main(["import", str(src), "--box-length", "10", "--mu", "0.5",
                 "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == len(frames) and summary["format"] == fmt and summary["seed"] == 3
    assert summary["status_rule"] == "the source's sliding flag"
    assert store.verify(out) == []
    with store.open_run(cd_run) as a, store.open_run(out) as b:
        assert np.array_equal(a.radius, b.radius) and np.array_equal(a.fixed, b.fixed)
        for name in ("step", "time", "theta_deg"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert b.seed == 3 and b.box_length == a.box_length
        cfg = config.from_dict(b.config)
        assert (cfg.scene.n, cfg.scene.mu, cfg.scene.mu_wall) == (40, 0.5, 0.5)
        assert cfg.protocol.theta_max_deg == 3.0 and cfg.protocol.tilt_per_step_deg == 0.1
        for k in range(a.n_frames):
            for name in ("position", "velocity", "omega", "rotation"):
                assert np.array_equal(getattr(a, name)(k), getattr(b, name)(k)), (name, k)
            # the same contacts, in the engines' order (Contact Dynamics stores its own)
            pa, fa, sa = a.contacts(k)
            pb, fb, sb = b.contacts(k)
            key = pa[:, 0] * 1000 + np.where(pa[:, 1] >= 0, pa[:, 1], 999 - pa[:, 1])
            o = np.argsort(key, kind="stable")
            assert np.array_equal(pa[o], pb) and np.array_equal(fa[o], fb) and np.array_equal(sa[o], sb)
        assert np.allclose(a.ke, b.ke, rtol=1e-12, atol=0)   # the same sum, another order
        attrs = b.f["import"].attrs
        assert attrs["format"] == fmt and json.loads(attrs["source"])["format"] == fmt
    _same_tables(_observables(cd_run), _observables(out), skip=SOLVER_COLUMNS)


def test_without_sliding_flags_the_coulomb_test_decides(cd_run, tmp_path, capsys):
    frames = frames_of(cd_run)
    for f in frames:
        del f["sliding"]
    src = write_npz(frames, tmp_path / "in")
    out = tmp_path / "run_0000.h5"
    assert main(["import", str(src), "--box-length", "10", "--mu", "0.5", "--eps", "0.01",
                 "--out", str(out)]) == 0
    assert "eps = 0.01" in json.loads(capsys.readouterr().out)["status_rule"]
    with store.open_run(out) as b:
        for k in (0, b.n_frames - 1):
            pair, force, status = b.contacts(k)
            act = force[:, 0] > 0
            assert np.array_equal(status > 0, act)
            assert np.array_equal(status[act] == 2, np.abs(force[act, 1]) >= 0.5 * force[act, 0] * 0.99)
        assert b.f["import"].attrs["eps"] == 0.01


# ------------------------------------------------------------------------------------------------
# LAMMPS dumps written by hand: ids, walls, signs

L = 6.0
# id: (type, x, y, radius, vx, vy, omegaz, floor (flag, fx, fy), sides (flag, fx, fy))
ATOMS = {5: (2, 2.0, 0.5, 0.5, 0.0, 0.0, 0.0, (0, 0, 0), (0, 0, 0)),
         10: (1, 2.0, 1.5, 0.5, 0.01, 0.0, 0.1, (0, 0, 0), (0, 0, 0)),
         20: (1, 0.5, 0.5, 0.5, 0.0, 0.0, 0.0, (1, 0.1, 1.0), (1, 0.3, 0.02)),
         30: (1, L - 0.5, 0.5, 0.5, 0.0, 0.0, 0.0, (1, -0.45, 0.9), (1, -0.4, 0.01))}
COLUMNS = "id type x y radius vx vy omegaz f_floor[1] f_floor[2] f_floor[3] f_sides[1] f_sides[2] f_sides[3]"
CONTACT_COLUMNS = "c_pa[1] c_pa[2] c_pl[1] c_pl[2] c_pl[3]"


def atom_dump(step: int, atoms=ATOMS, columns=COLUMNS, order=(30, 5, 20, 10)) -> str:
    lines = [f"ITEM: TIMESTEP\n{step}\nITEM: NUMBER OF ATOMS\n{len(order)}\n"
             "ITEM: BOX BOUNDS ff fm pp\n-2 8\n-2 10\n-0.5 0.5\n" f"ITEM: ATOMS {columns}\n"]
    for i in order:
        t, x, y, r, vx, vy, w, fl, si = atoms[i]
        lines.append(" ".join(f"{v:g}" for v in (i, t, x, y, r, vx, vy, w, *fl, *si)) + "\n")
    return "".join(lines)


def contact_dump(step: int, rows=((5, 10, 0.5, -0.2, 0.0),)) -> str:
    """Rows: patom1, patom2, f_n, tangential force on atom 1 (x, y)."""
    head = (f"ITEM: TIMESTEP\n{step}\nITEM: NUMBER OF ENTRIES\n{len(rows)}\n"
            "ITEM: BOX BOUNDS ff fm pp\n-2 8\n-2 10\n-0.5 0.5\n" f"ITEM: ENTRIES {CONTACT_COLUMNS}\n")
    return head + "".join(" ".join(f"{v:g}" for v in row) + "\n" for row in rows)


LAMMPS_ARGS = ["--contact-columns", "id1=c_pa[1],id2=c_pa[2],fn=c_pl[1],ftx=c_pl[2],fty=c_pl[3]",
               "--fixed-types", "2", "--wall", "f_floor=floor", "--wall", "f_sides=sides",
               "--box-length", str(L), "--mu", "0.5", "--timestep", "0.01"]


def lammps_inputs(d, atoms=None, contacts=None, angles="step,theta_deg\n0,0.0\n50,0.5\n100,1.0\n"):
    d.mkdir(parents=True, exist_ok=True)
    (d / "atoms.dump").write_text(atoms if atoms is not None else atom_dump(0) + atom_dump(100))
    with gzip.open(d / "contacts.dump.gz", "wt") as fh:   # compressed dumps are read too
        fh.write(contacts if contacts is not None else contact_dump(0) + contact_dump(100))
    (d / "angles.csv").write_text(angles)
    return [str(d / "atoms.dump"), "--contacts", str(d / "contacts.dump.gz"),
            "--angles", str(d / "angles.csv")]


def test_lammps_dumps_by_hand_ids_walls_and_signs(tmp_path, capsys):
    """Grains by id (5 fixed, 10, 20, 30 -> 0..3); the pair's tangential force (0.2 to -x on
    atom 10 sitting on 5, listed as seen from 5) is -0.2 along t = (-n_y, n_x) either way round;
    floor: f_n = f_y, f_t = -f_x; the sides fix: the left wall f_n = f_x, f_t = f_y, the right
    one f_n = -f_x, f_t = -f_y; the Coulomb test at mu 0.5 marks 30's floor contact sliding."""
    out = tmp_path / "run_0000.h5"
    assert main(["import", *lammps_inputs(tmp_path / "in"), *LAMMPS_ARGS, "--out", str(out)]) == 0
    capsys.readouterr()
    with store.open_run(out) as r:
        assert r.n_frames == 2 and r.step.tolist() == [0, 100] and r.time.tolist() == [0.0, 1.0]
        assert r.theta_deg.tolist() == [0.0, 1.0] and r.fixed.tolist() == [True, False, False, False]
        assert np.array_equal(r.position(1)[1], [2.0, 1.5]) and r.velocity(0)[1, 0] == 0.01
        pair, force, status = r.contacts(0)
        assert pair.tolist() == [[0, 1], [2, -1], [2, -2], [3, -1], [3, -3]]
        assert np.allclose(force, [[0.5, -0.2], [1.0, -0.1], [0.3, 0.02], [0.9, 0.45], [0.4, -0.01]],
                           rtol=0, atol=1e-15)
        assert status.tolist() == [1, 1, 1, 2, 1]
        m = np.pi * 0.25
        assert r.ke[0] == pytest.approx(0.5 * m * (0.01**2 + 0.5 * 0.25 * 0.1**2), rel=1e-12)
    swapped = tmp_path / "swapped"
    rows = ((10, 5, 0.5, 0.2, 0.0),)   # the same contact seen from atom 10: the force on it is +0.2 x
    out2 = tmp_path / "run_0001.h5"
    assert main(["import", *lammps_inputs(swapped, contacts=contact_dump(0, rows) + contact_dump(100, rows)),
                 *LAMMPS_ARGS, "--out", str(out2)]) == 0
    with store.open_run(out2) as r:
        assert r.contacts(0)[1][0].tolist() == [0.5, -0.2]


def test_the_help_explains_the_formats(capsys):
    with pytest.raises(SystemExit) as e:
        main(["import", "--help"])
    text = capsys.readouterr().out
    assert e.value.code == 0
    for words in ("LAMMPS dumps", "NPZ frames", "a CSV set", "|f_t| >= mu f_n (1 - eps)",
                  "--contact-columns", "--wall", "--angles", "examples:"):
        assert words in text, words


# ------------------------------------------------------------------------------------------------
# refusals: one line naming the field and the frame, nothing written


def small_frames() -> list[dict]:
    """Three frames of a hand-made pile: fixed grains 0, 1; grain 2 on them, grain 3 on the floor."""
    out = []
    for k in range(3):
        out.append(dict(step=10 * k, time=0.1 * k, theta_deg=0.5 * k, id=np.array([0, 1, 2, 3]),
                        x=np.array([1.0, 2.0, 1.5, 3.5]), y=np.array([0.5, 0.5, 1.366, 0.5]),
                        radius=np.full(4, 0.5), fixed=np.array([1, 1, 0, 0]),
                        id1=np.array([0, 1, 3]), id2=np.array([2, 2, -1]),
                        fn=np.array([0.4, 0.4, 0.8]), ft=np.array([0.01, -0.01, 0.0])))
    return out


def _set(k, field, value):
    def change(frames):
        frames[k][field] = value
    return change


def _drop(k, field):
    def change(frames):
        del frames[k][field]
    return change


def _swap_steps(frames):
    frames[1]["step"], frames[2]["step"] = frames[2]["step"], frames[1]["step"]


PLAIN_REFUSALS = [
    (_drop(1, "radius"), "frame_1.npz: no field 'radius'"),
    (_set(0, "thetadeg", 1.0), "frame_0.npz: unknown field 'thetadeg'"),
    (_set(2, "x", np.array([1.0, 2.0, np.nan, 3.5])), "frame 2 (step 20, frame_2.npz): x of grain id 2 is nan"),
    (_set(1, "id", np.array([0, 1, 2, 2])), "frame 1 (step 10, frame_1.npz): grain id 2 appears twice"),
    (_swap_steps, "frame 2 (step 10, frame_2.npz): frames out of order: step 10 follows step 20"),
    (_set(2, "theta_deg", 0.2), "frame 2 (step 20, frame_2.npz): theta_deg goes backwards"),
    (_set(1, "theta_deg", 95.0), "frame 1 (step 10, frame_1.npz): theta_deg = 95.0 is outside [0, 90]"),
    (_set(1, "id", np.array([0, 1, 2, 7])), "frame 1 (step 10, frame_1.npz): grain id 3 of frame 0 is missing"),
    (_set(2, "radius", np.array([0.5, 0.5, 0.5, 0.45])), "frame 2 (step 20, frame_2.npz): radius of grain id 3"),
    (_set(1, "id2", np.array([2, 9, -1])), "frame 1 (step 10, frame_1.npz): contact id2 9 is no grain"),
    (_set(0, "id2", np.array([2, 2, 3])), "frame 0 (step 0, frame_0.npz): contact row 2 joins grain id 3 to itself"),
    (_set(0, "id1", np.array([0, 0, 3])), "frame 0 (step 0, frame_0.npz): the contact of grain id 0 and grain id 2 is listed twice"),
    (_set(1, "fn", np.array([0.4, np.inf, 0.8])), "frame 1 (step 10, frame_1.npz): contact fn in row 1 is inf"),
    (_set(2, "x", np.array([1.0, 2.0, 1.5, 6.5])), "frame 2 (step 20, frame_2.npz): x, y of grain id 3, (6.5, 0.5) d, is outside the box"),
    (_set(0, "radius", np.full(4, 0.001)), "mean diameter is 0.002 d"),
    (_set(0, "fixed", np.array([1, 1, 1, 1])), "frame 0 (step 0, frame_0.npz): every grain is fixed"),
    (_set(1, "step", 10.5), "frame_1.npz: step holds 10.5, not an integer"),
]


def _listing(d):
    return sorted(p.relative_to(d).as_posix() for p in d.rglob("*"))


@pytest.mark.parametrize("change, message", PLAIN_REFUSALS, ids=[m[:40] for _, m in PLAIN_REFUSALS])
def test_plain_refusals_name_the_field_and_the_frame(tmp_path, capsys, change, message):
    frames = small_frames()
    change(frames)
    write_npz(frames, tmp_path / "in")
    before = _listing(tmp_path)
    rc = main(["import", str(tmp_path / "in"), "--box-length", "5", "--mu", "0.5",
               "--out", str(tmp_path / "out" / "run_0000.h5")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and message in err[0], err
    assert _listing(tmp_path) == before   # nothing written, not even the directory


def test_the_small_pile_itself_imports(tmp_path, capsys):
    """The refusals above change one thing each in an input that passes."""
    write_npz(small_frames(), tmp_path / "in")
    out = tmp_path / "run_0000.h5"
    assert main(["import", str(tmp_path / "in"), "--box-length", "5", "--mu", "0.5", "--out", str(out)]) == 0
    with store.open_run(out) as r:
        assert r.n_frames == 3 and r.contacts(2)[0].tolist() == [[0, 2], [1, 2], [3, -1]]
        assert np.isnan(r.ke).all() and np.isnan(r.velocity(0)).all()   # no velocities given


def _csv_missing_column(d):
    import pandas as pd

    t = pd.read_csv(d / "grains.csv")
    t.drop(columns=["radius"]).to_csv(d / "grains.csv", index=False)


def _dump_without_radius(d):
    (d / "atoms.dump").write_text(atom_dump(0, columns=COLUMNS.replace("radius", "rad")) + atom_dump(100))


def _dump_cut_short(d):
    text = atom_dump(0) + atom_dump(100)
    (d / "atoms.dump").write_text(text[: text.rindex("\n", 0, len(text) - 1) + 1])


def _dump_steps_twice(d):
    (d / "atoms.dump").write_text(atom_dump(0) + atom_dump(100) + atom_dump(100))


def _contacts_missing(d):
    with gzip.open(d / "contacts.dump.gz", "wt") as fh:
        fh.write(contact_dump(0) + contact_dump(50))


def _no_angle(d):
    (d / "angles.csv").write_text("step,theta_deg\n0,0.0\n")


REFUSALS = [
    ("csv", _csv_missing_column, [], "grains.csv: no column 'radius'"),
    ("lammps", _dump_without_radius, [], "atoms.dump, step 0: no column 'radius'"),
    ("lammps", _dump_cut_short, [], "atoms.dump, step 100: the frame is cut short: 3 of its 4 rows"),
    ("lammps", _dump_steps_twice, [], "atoms.dump, step 100: frames out of order: timestep 100 follows timestep 100"),
    ("lammps", _contacts_missing, [], "frame 1 (step 100, atoms.dump): no contact frame at timestep 100"),
    ("lammps", _no_angle, [], "frame 1 (step 100, atoms.dump): --angles has no row for step 100"),
    ("lammps", None, ["--atom-columns", "gx=v_gx"], "--atom-columns: give both gx and gy"),
    ("lammps", None, ["--contact-columns", "id1=c_pa[1],id2=c_pa[2],fn=c_pl[1]"], "--contact-columns: map id1, id2, fn and ft"),
    ("lammps", None, ["--wall", "f_floor=ceiling"], "--wall 'f_floor=ceiling': expected FIX=PLANE"),
    ("npz", None, ["--contacts", "x.dump"], "--contacts is for LAMMPS dumps"),
    ("npz", None, ["--eps", "1.5"], "--eps must be in [0, 1)"),
    ("npz", None, ["--set", "scene.mu=0.3"], "--set scene.mu=0.3: scene.mu is set by --mu"),
    ("npz", None, ["--set", "protocol.frame_every=0"], "protocol.frame_every = 0 is out of range"),
]


@pytest.mark.parametrize("fmt, change, extra, message", REFUSALS, ids=[r[3][:40] for r in REFUSALS])
def test_refusals_of_each_format_are_one_line_and_write_nothing(tmp_path, capsys, fmt, change, extra, message):
    d = tmp_path / "in"
    if fmt == "lammps":
        args = lammps_inputs(d)
        base = [a for a in LAMMPS_ARGS]
        for k in range(0, len(extra), 2):   # an option given replaces the base's
            if extra[k] in base and extra[k] != "--wall":
                i = base.index(extra[k])
                del base[i:i + 2]
        if "--wall" in extra:
            base = [a for k, a in enumerate(base) if not (a == "--wall" or (k and base[k - 1] == "--wall"))]
        args += base
    else:
        (write_npz if fmt == "npz" else write_csv)(small_frames(), d)
        args = [str(d), "--box-length", "5", "--mu", "0.5"]
    if change is not None:
        change(d)
    before = _listing(tmp_path)
    rc = main(["import", *args, *extra, "--out", str(tmp_path / "run_0000.h5")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and message in err[0], err
    assert _listing(tmp_path) == before


def test_an_existing_run_file_is_kept_unless_forced_and_whole(tmp_path, capsys):
    write_npz(small_frames(), tmp_path / "in")
    out = tmp_path / "run_0000.h5"
    args = ["import", str(tmp_path / "in"), "--box-length", "5", "--mu", "0.5", "--out", str(out)]
    assert main(args) == 0
    first = out.read_bytes()
    capsys.readouterr()
    assert main(args) == 2
    assert "exists; pass --force" in capsys.readouterr().err
    bad = small_frames()
    bad[2]["theta_deg"] = 0.1
    write_npz(bad, tmp_path / "in")
    assert main(args + ["--force"]) == 2 and out.read_bytes() == first   # refused: the old file stays
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "run_0000.h5"]


def test_an_interrupted_write_leaves_nothing(tmp_path, monkeypatch, capsys):
    """A kill (KeyboardInterrupt) in the middle of the write: no run file, no temporary."""
    from tiltpile.store import RunWriter

    write_npz(small_frames(), tmp_path / "in")
    calls = []

    def append(self, frame, _orig=RunWriter.append):
        calls.append(frame.index)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return _orig(self, frame)

    monkeypatch.setattr(RunWriter, "append", append)
    rc = main(["import", str(tmp_path / "in"), "--box-length", "5", "--mu", "0.5",
               "--out", str(tmp_path / "run_0000.h5")])
    assert rc == 130 and "nothing was written" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_the_converter_from_python():
    """The checks are those of the library (tiltpile.importers), not only of the command line."""
    conv = Converter(box_length=5.0, mu=0.5)
    f = small_frames()[0]
    raw = RawFrame(where="mine", step=0, time=0.0, theta_deg=0.0, id=f["id"],
                   position=np.column_stack([f["x"], f["y"]]), radius=f["radius"], fixed=f["fixed"],
                   velocity=None, omega=None, rotation=None, id1=f["id1"], id2=f["id2"], fn=f["fn"],
                   ft=f["ft"], sliding=None)
    frame = conv.convert(raw)
    assert frame.pair.tolist() == [[0, 2], [1, 2], [3, -1]] and frame.status.tolist() == [1, 1, 1]
    raw.step = 0
    with pytest.raises(InputError, match=r"^frame 1 \(step 0, mine\): frames out of order"):
        conv.convert(raw)


def test_frames_beyond_the_buffer_are_read_again_to_the_same_file(cd_run, tmp_path):
    """Past ``buffer_bytes`` the importer reads its input a second time to write it: the same
    frames."""
    from tiltpile.importers import NpzReader, import_run

    src = write_npz(frames_of(cd_run), tmp_path / "in")
    kept, again = tmp_path / "a" / "run_0000.h5", tmp_path / "b" / "run_0000.h5"
    import_run(NpzReader([src]), kept, box_length=10.0, mu=0.5)
    import_run(NpzReader([src]), again, box_length=10.0, mu=0.5, buffer_bytes=0)
    with store.open_run(kept) as a, store.open_run(again) as b:
        assert a.frames_digest() == b.frames_digest() and a.config_hash == b.config_hash
