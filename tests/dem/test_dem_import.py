"""`tiltpile import` on data no one wrote for it: the DEM engine's own LAMMPS dumps of a tiny pile
(`tiltpile dem --keep-dumps`), imported with the command their README gives, against the run
file the DEM wrote directly (docs/import.md, "Checked on data no one wrote for it").

Tolerances and why:
- full precision (the dumps as kept, %.17g): every array the analysis reads is equal bit for bit
  but the forces (1 ulp: the importer takes the branch vector from the positions, the engine
  from LAMMPS' pair/local) and the angle, which the importer recovers from the gravity vector
  LAMMPS applied, atan2(g_x, -g_y): 3e-14 deg off the protocol's; so every observable is equal
  but those holding the angle, to 1e-12 deg;
- LAMMPS' default precision (the same dumps at %g, 6 significant digits, as every dump without
  `dump_modify format` holds them; --eps 1e-4, against the DEM run analysed with eps = 1e-4):
  every count is equal (a count could only change through a contact within 1e-5 of the Coulomb
  threshold or a grain within 1e-5 d of a layer rule's edge: none here), lengths to 1e-4 d (6
  digits of ~10 d), the tilt angles to 1e-4 deg and the clusters' axes to 1e-3 deg, energies and
  speeds to 1e-4 relative.
"""

from __future__ import annotations

import glob
import shlex
import warnings

import numpy as np
import pytest

from tiltpile import store
from tiltpile.cli import main

TINY = ["scene.n=40", "scene.box_length=10.0", "protocol.theta_max_deg=30.0",
        "protocol.tilt_per_step_deg=0.05", "protocol.checkpoint_every=20"]
ANGLE_COLUMNS = ("theta_deg", "theta_m", "theta_to_onset")


def _dem(out, *extra):
    args = ["dem", "--preset", "smoke", "--seed", "0", "--out", str(out), "--quiet", *extra]
    assert main(args + [a for kv in TINY for a in ("--set", kv)]) == 0


@pytest.fixture(scope="module")
def dem_runs(tmp_path_factory):
    """A 40-grain DEM pile tilted to 30 deg (61 frames, four avalanches), with its dumps kept;
    and the same run without them: (run with dumps, dumps directory, run without)."""
    d = tmp_path_factory.mktemp("dem")
    _dem(d / "kept" / "run_0000.h5", "--keep-dumps", str(d / "dumps"))
    _dem(d / "plain" / "run_0000.h5")
    return d / "kept" / "run_0000.h5", d / "dumps", d / "plain" / "run_0000.h5"


def _readme_command(dumps, out) -> list[str]:
    """The `tiltpile import` command of DIR/README.txt, its globs expanded as a shell would."""
    line = next(s for s in (dumps / "README.txt").read_text().splitlines()
                if s.strip().startswith("tiltpile import"))
    args = []
    for a in shlex.split(line)[1:]:
        args += sorted(glob.glob(a)) if "*" in a else [str(out) if a == "RUN.h5" else a]
    return args


def _observables(path, **params):
    from tiltpile.analysis.tables import run_observables

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # a 40-grain pile is below the cutoff's resolution
        return run_observables(path, **params)


def test_keeping_the_dumps_changes_nothing(dem_runs):
    kept, dumps, plain = dem_runs
    with store.open_run(kept) as a, store.open_run(plain) as b:
        assert a.frames_digest() == b.frames_digest() and a.config_hash == b.config_hash
        n = a.n_frames
        steps = a.step.tolist()
    assert sorted(p.name for p in dumps.iterdir()) == sorted(
        ["README.txt"] + [f"{kind}.{s}.dump" for s in steps for kind in ("atoms", "contacts")])
    assert n == 61


@pytest.mark.filterwarnings("ignore:avalanche cutoff")
def test_the_dumps_imported_give_the_dem_runs_observables(dem_runs, tmp_path, capsys):
    kept, dumps, _ = dem_runs
    out = tmp_path / "imported" / "run_0000.h5"
    assert main(_readme_command(dumps, out)) == 0
    capsys.readouterr()
    assert store.verify(out) == []
    with store.open_run(kept) as a, store.open_run(out) as b:
        assert b.n_frames == a.n_frames and b.seed == a.seed and b.box_length == a.box_length
        assert np.array_equal(a.radius, b.radius) and np.array_equal(a.fixed, b.fixed)
        for name in ("step", "time", "ke", "max_overlap"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert np.allclose(a.theta_deg, b.theta_deg, rtol=0, atol=1e-12)
        for k in range(a.n_frames):
            for name in ("position", "velocity", "omega"):
                assert np.array_equal(getattr(a, name)(k), getattr(b, name)(k)), (name, k)
            pa, fa, sa = a.contacts(k)
            pb, fb, sb = b.contacts(k)
            assert np.array_equal(pa, pb) and np.array_equal(sa, sb), k
            assert np.allclose(fa, fb, rtol=0, atol=1e-15), k
        assert "eps = 1e-09" in b.f["import"].attrs["status_rule"]
    fa, ca = _observables(kept)
    fb, cb = _observables(out)
    assert fa["n_lost"].max() > 0 and fa["onset"].sum() >= 2 and len(ca) > 100   # something happens
    for x, y in ((fa, fb), (ca, cb)):
        assert list(x.columns) == list(y.columns) and len(x) == len(y)
        for c in x.columns:
            if c in ANGLE_COLUMNS:
                assert np.allclose(x[c], y[c], rtol=0, atol=1e-12, equal_nan=True), c
            else:
                assert np.array_equal(x[c].to_numpy(), y[c].to_numpy(), equal_nan=True), c
    # the directory serves the commands that read run files
    d = out.parent
    assert main(["verify", str(d)]) == 0
    assert main(["observables", str(d), "--workers", "1", "--quiet"]) == 0
    assert main(["record", str(d), "--out", str(tmp_path / "records"), "--workers", "1", "--quiet"]) == 0
    assert (tmp_path / "records" / "run_0000.npz").is_file()


def _at_default_precision(src, dst):
    """The dumps as LAMMPS writes them without dump_modify format: every value of the ATOMS and
    ENTRIES rows with %g (6 significant digits; C's %g and Python's are the same)."""
    dst.mkdir()
    for f in src.glob("*.dump"):
        out, rows, n = [], 0, 0
        for line in f.read_text().splitlines():
            if rows:
                out.append(" ".join("%g" % float(t) for t in line.split()))
                rows -= 1
                continue
            if out and out[-1].startswith("ITEM: NUMBER OF"):
                n = int(line)
            out.append(line)
            if line.startswith(("ITEM: ATOMS", "ITEM: ENTRIES")):
                rows = n
        (dst / f.name).write_text("\n".join(out) + "\n")
    (dst / "README.txt").write_text((src / "README.txt").read_text().replace(str(src), str(dst)))
    return dst


def test_at_lammps_default_precision_every_count_is_the_same(dem_runs, tmp_path, capsys):
    kept, dumps, _ = dem_runs
    rounded = _at_default_precision(dumps, tmp_path / "rounded")
    out = tmp_path / "run_0000.h5"
    args = _readme_command(rounded, out)
    args[args.index("--eps") + 1] = "1e-4"
    assert main(args) == 0
    capsys.readouterr()
    fa, ca = _observables(kept, eps=1e-4)
    fb, cb = _observables(out)
    lengths = ("mean_displacement", "max_displacement", "rg_long", "rg_short", "x_com", "y_com")
    relative = ("ke_trans", "ke_rot", "speed_max")
    for x, y in ((fa, fb), (ca, cb)):
        assert list(x.columns) == list(y.columns) and len(x) == len(y)
        for c in x.columns:
            a, b = x[c].to_numpy(), y[c].to_numpy()
            if c in lengths:
                assert np.allclose(a, b, rtol=0, atol=1e-4, equal_nan=True), c
            elif c in ANGLE_COLUMNS:
                assert np.allclose(a, b, rtol=0, atol=1e-4, equal_nan=True), c
            elif c in ("orientation_deg", "phi_deg"):   # a cluster's axis from rounded positions
                assert np.allclose(a, b, rtol=0, atol=1e-3, equal_nan=True), c
            elif c in relative:
                assert np.allclose(a, b, rtol=1e-4, atol=1e-12, equal_nan=True), c
            else:   # counts, and what counts make: z, n_m, lost fractions, clusters, avalanches
                assert np.array_equal(a, b, equal_nan=True), c
