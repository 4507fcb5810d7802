"""The export is read back by independent readers (ASE for extended XYZ, meshio for VTK) and
every column and frame is checked against the run file."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import ase.io
import meshio
import numpy as np
import pytest

from tiltpile.cli import main
from tiltpile.store import open_run
from tiltpile.view.fields import FrameFields, parse_frames

RTOL = 1e-9   # floats are written with 10 significant digits


def _close(a, b):
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=1e-300)


@pytest.mark.parametrize("frames", [None, "3::7"])
def test_extxyz_read_back_by_ase(tiny_run, tmp_path, frames, capsys):
    out = tmp_path / "run.xyz"
    argv = ["export", str(tiny_run), "--format", "extxyz", "--out", str(out), "--quiet"]
    assert main(argv + (["--frames", frames] if frames else [])) == 0
    images = ase.io.read(out, index=":", format="extxyz")
    with open_run(tiny_run) as run:
        sel = parse_frames(frames, run.n_frames)
        assert len(images) == len(sel)
        ff = FrameFields(run)
        for atoms, k in zip(images, sel):
            f = ff.fields(k)
            n = f["radius"].size
            assert len(atoms) == n
            assert set(atoms.get_chemical_symbols()) == {"X"}
            info = atoms.info
            assert (info["frame"], info["step"]) == (k, run.step[k])
            _close(info["time"], run.time[k])
            _close(info["theta_deg"], run.theta_deg[k])
            _close(info["box_length"], run.box_length)
            t = np.radians(run.theta_deg[k])
            _close(info["gravity"], [np.sin(t), -np.cos(t), 0.0])
            assert not atoms.pbc.any()
            assert atoms.cell[0, 0] == pytest.approx(run.box_length)
            pos = atoms.get_positions()
            _close(pos[:, :2], run.position(k))
            assert np.all(pos[:, 2] == 0)
            a = atoms.arrays
            _close(a["radius"], run.radius)
            _close(a["velo"][:, :2], run.velocity(k))
            assert np.all(a["velo"][:, 2] == 0)
            _close(a["omega"], run.omega(k))
            np.testing.assert_array_equal(a["fixed"], run.fixed)
            np.testing.assert_array_equal(a["id"], np.arange(n))
            for name in ("n_active", "n_mobilized", "cluster", "failing", "failing_next"):
                np.testing.assert_array_equal(a[name], f[name], err_msg=name)
        if frames is None:
            assert sum(im.arrays["failing"].sum() for im in images) > 0
            assert max(im.arrays["cluster"].max() for im in images) >= 0


def _pvd(path):
    root = ET.parse(path).getroot()
    assert root.attrib["type"] == "Collection"
    return [ds.attrib for ds in root.iter("DataSet")]


def test_vtk_read_back_by_meshio(tiny_run, tmp_path):
    out = tmp_path / "pile.pvd"
    assert main(["export", str(tiny_run), "--format", "vtk", "--out", str(out), "--quiet",
                 "--frames", "::4"]) == 0
    entries = _pvd(out)
    with open_run(tiny_run) as run:
        sel = parse_frames("::4", run.n_frames)
        assert len(entries) == 2 * len(sel)
        assert [e["part"] for e in entries] == ["0", "1"] * len(sel)
        ff = FrameFields(run)
        for idx, k in enumerate(sel):
            f = ff.fields(k)
            n = f["radius"].size
            g_entry, c_entry = entries[2 * idx], entries[2 * idx + 1]
            assert float(g_entry["timestep"]) == pytest.approx(run.theta_deg[k])
            g = meshio.read(tmp_path / g_entry["file"])
            _close(g.points[:, :2], run.position(k))
            assert np.all(g.points[:, 2] == 0)
            assert [(c.type, len(c.data)) for c in g.cells] == [("vertex", n)]
            pd = g.point_data
            _close(pd["radius"], run.radius)
            _close(pd["velocity"][:, :2], run.velocity(k))
            _close(pd["omega"], run.omega(k))
            np.testing.assert_array_equal(pd["fixed"], run.fixed.astype(np.uint8))
            np.testing.assert_array_equal(pd["id"], np.arange(n))
            for name in ("n_active", "n_mobilized", "cluster", "failing", "failing_next"):
                np.testing.assert_array_equal(pd[name], f[name], err_msg=name)
            assert g.field_data["theta_deg"][0] == pytest.approx(run.theta_deg[k])
            assert int(g.field_data["step"][0]) == run.step[k]

            c = meshio.read(tmp_path / c_entry["file"])
            (block,) = c.cells
            assert block.type == "line" and len(block.data) == len(f["pair"])
            cd = {name: arr[0] for name, arr in c.cell_data.items()}
            _close(cd["f_n"], f["force"][:, 0])
            _close(cd["f_t"], f["force"][:, 1])
            np.testing.assert_array_equal(cd["status"], f["status"])
            np.testing.assert_array_equal(cd["i"], f["pair"][:, 0])
            np.testing.assert_array_equal(cd["j"], f["pair"][:, 1])
            np.testing.assert_array_equal(cd["mobilized"], f["mobilized"].astype(np.uint8))
            # grain-grain lines join the two centres; wall lines end on the wall
            ends = c.points[block.data][:, :, :2]
            _close(ends[:, 0], run.position(k)[f["pair"][:, 0]])
            gg = f["pair"][:, 1] >= 0
            _close(ends[gg, 1], run.position(k)[f["pair"][gg, 1]])
            floor = f["pair"][:, 1] == -1
            assert np.all(ends[floor, 1, 1] == 0)
            # the active lines of each grain are its n_active
            act = cd["active"].astype(bool)
            per_grain = np.bincount(block.data[act].ravel(), minlength=len(c.points))[:n]
            np.testing.assert_array_equal(per_grain, pd["n_active"])


def test_export_refuses_bad_input(tiny_run, tmp_path, capsys):
    cases = [
        (["--format", "vtk", "--out", str(tmp_path / "a.xyz")], "NAME.pvd"),
        (["--format", "extxyz", "--out", str(tmp_path / "a.xyz"), "--frames", "9:3"], "selects no frame"),
        (["--format", "extxyz", "--out", str(tmp_path / "nodir" / "a.xyz")], "no such directory"),
    ]
    for extra, msg in cases:
        assert main(["export", str(tiny_run), "--quiet", *extra]) == 2
        err = capsys.readouterr().err
        assert msg in err and err.startswith("tiltpile export: error:") and err.count("\n") == 1
    assert main(["export", str(tmp_path / "none.h5"), "--format", "extxyz",
                 "--out", str(tmp_path / "a.xyz")]) == 2
    assert "none.h5" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())
