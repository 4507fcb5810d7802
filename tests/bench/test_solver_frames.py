"""``benchmarks.solver_frames``: one step re-solved at each cap, sweep order and start, on a
tiny run (60 grains) and a tiny bench pile; the table's shape, a converged step's n_m the same at
every cap above its convergence, the run's own setting giving the stored frame back, and bad
input refused in one line."""

from __future__ import annotations

import json

import pytest

from tiltpile import config
from benchmarks import solver_frames as sf
from tiltpile.runner import simulate

CAPS = (20, 60, 200, 2000)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    cfg = config.load("smoke", None, ["scene.n=60", "scene.box_length=10",
                                      "protocol.theta_max_deg=0.5", "protocol.frame_every=5"])
    out = tmp_path_factory.mktemp("solver_frames") / "run_0001.h5"
    simulate(cfg, 1, out, progress=False)
    return out


@pytest.fixture(scope="module")
def measured(tiny_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("solver_frames_out")
    code = sf.main(["--run", str(tiny_run), "--frames", "3,10", "--caps", ",".join(map(str, CAPS)),
                    "--out", str(out), "--quiet"])
    assert code == 0
    return json.loads((out / "solver_frames.json").read_text()), (out / "solver_frames.md").read_text()


def test_the_table_has_one_row_per_order_start_and_cap(measured):
    result, md = measured
    assert result["caps"] == list(CAPS) and result["orders"] == list(sf.ORDERS)
    assert len(result["states"]) == 2
    for st in result["states"]:
        rows = st["rows"]
        assert len(rows) == len(CAPS) * len(sf.ORDERS) * len(sf.STARTS)
        assert {(r["order"], r["start"], r["cap"]) for r in rows} == {
            (o, s, c) for o in sf.ORDERS for s in sf.STARTS for c in CAPS}
        for r in rows:
            assert r["sweeps"] <= r["cap"] and r["sliding"] <= r["active"]
            assert 0 <= r["n_m"] <= r["z"] and r["dv"] >= 0
        ref = [r for r in rows if r["order"] == st["run_order"] and r["start"] == "warm"
               and r["cap"] == CAPS[-1]]
        assert ref[0]["dv"] == 0.0
    # markdown: per state two tables of 8 rows, one column per cap besides order, start and one more
    tables = [ln for ln in md.splitlines() if ln.startswith("| ") and not ln.startswith("| order")]
    assert len(tables) == 2 * 2 * len(sf.ORDERS) * len(sf.STARTS)
    assert all(ln.count("|") == len(CAPS) + 4 for ln in tables)
    assert md.startswith("Command: `python -m benchmarks.solver_frames --run ")


def test_a_converged_step_gives_the_same_n_m_at_every_cap_above_its_convergence(measured):
    result, _ = measured
    seen = 0
    for st in result["states"]:
        series = {}
        for r in st["rows"]:
            series.setdefault((r["order"], r["start"]), []).append(r)
        for rs in series.values():
            rs.sort(key=lambda r: r["cap"])
            done = [r for r in rs if r["converged"]]
            if not done:
                continue
            first = done[0]
            for r in rs:
                if r["cap"] >= first["cap"]:
                    seen += 1
                    assert r["converged"] and r["sweeps"] == first["sweeps"] < first["cap"] or \
                        r is first
                    for k in ("n_m", "z", "sliding", "active", "dv", "residual"):
                        assert r[k] == first[k], (k, r, first)
            s = next(x for x in st["summary"]["series"]
                     if (x["order"], x["start"]) == (rs[0]["order"], rs[0]["start"]))
            assert s["settled_from"] is not None and s["settled_from"] <= first["cap"]
    assert seen >= 4  # the warm starts of the quiet tiny run converge


def test_the_runs_own_setting_gives_the_stored_frame_back(measured):
    result, _ = measured
    for st in result["states"]:
        ar, stored = st["as_run"], st["stored"]
        if not stored["sweeps"] < st["run_cap"]:
            continue  # a capped step is replayed only approximately (runner.system_from_frame)
        assert ar["sweeps"] == stored["sweeps"]
        assert ar["n_m"] == stored["n_m"] and ar["z"] == stored["z"]
        assert stored["max_position_difference"] < 1e-9


def test_a_bench_pile_state(tmp_path):
    st = sf.state_from_bench(60, 0.25, preset="smoke", cache=tmp_path)
    assert st.theta_deg == pytest.approx(0.25 + st.dtheta_deg)
    (res,) = sf.measure([st], caps=(30, 3000), orders=("interleaved", "forward"),
                        starts=("warm",), progress=False)
    assert len(res["rows"]) == 4 and res["source"]["bench"] == 60
    assert "stored" not in res


@pytest.mark.parametrize("argv, says", [
    ([], "nothing to measure"),
    (["--bench", "4000"], "expected N:DEG"),
    (["--bench", "60:95"], "DEG must be in"),
    (["--bench", "60:5", "--caps", "0,300"], "--caps"),
    (["--bench", "60:5", "--caps", "300,x"], "--caps"),
    (["--bench", "60:5", "--orders", "forward,sideways"], "--orders"),
    (["--bench", "60:5", "--starts", "hot"], "--starts"),
    (["--bench", "60:5", "--preset", "nope"], "--preset"),
    (["--bench", "60:5", "--bogus"], "unrecognized arguments"),
    (["--run", "/nonexistent/run.h5", "--frames", "3"], "no such file"),
    (["--frames", "3"], "go together"),
    ("RUN --frames 0", "out of range"),
    ("RUN --frames 999", "out of range"),
])
def test_bad_input_is_refused_in_one_line(argv, says, tiny_run, capsys):
    if isinstance(argv, str):
        argv = [str(tiny_run) if a == "RUN" else a for a in argv.split()]
        argv = ["--run", *argv]
    assert sf.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("python -m benchmarks.solver_frames: error: ")
    assert says in err


def test_a_file_that_is_not_a_run_is_refused_in_one_line(tmp_path, capsys):
    bad = tmp_path / "run.h5"
    bad.write_bytes(b"not hdf5")
    assert sf.main(["--run", str(bad), "--frames", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a readable HDF5 file" in err
