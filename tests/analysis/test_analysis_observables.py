"""End to end: a tiny hand-built run file -> per-frame and per-cluster tables, and the cache.

The pile (width 4, ``pile_factory(4, 4)``): fixed row 0 = grains 0-3; row 1 = 4, 5, 6 (x = 1, 2, 3);
row 2 = 7-10 (x = 0.5 ... 3.5, touching both walls); row 3 = 11, 12, 13; row 4 (top) = 14-17.
Bulk = rows 2 and 3. Every geometric contact has f_n = 1.

frame 0 (theta 0):    at rest, nothing sliding.
frame 1 (theta 0.05): contact (8, 9) slides -> one cluster {8, 9}; grain 12 moves (v = (1, 0), omega = 2).
frame 2 (theta 0.10): grain 15 lifted by 0.3 d (its 4 contacts gone), (8, 9) open; list shuffled.
"""

import os

import numpy as np
import pandas as pd
import pytest

from tiltpile.analysis import observables as ob
from tiltpile.analysis import tables
from tiltpile.analysis import FRAME_COLUMNS, CLUSTER_COLUMNS, compute_observables, load_observables

# the hand-built run has 3 frames and ~40 contacts, far below what the 2% cutoff resolves: the
# ResolutionWarning that segment_avalanches issues for it is expected (tests/test_stability.py)
pytestmark = pytest.mark.filterwarnings("ignore::tiltpile.analysis.ResolutionWarning")

REQUIRED_FRAME = ["run", "frame", "theta_deg", "z", "n_m", "dz_gen", "ke_trans", "ke_rot",
                  "lost_fraction", "n_failing", "largest_cluster", "n_clusters", "cluster_fraction",
                  "avalanching", "theta_to_onset", "max_displacement"]
REQUIRED_CLUSTER = ["run", "frame", "size", "z", "n_m", "dz", "orientation_deg"]


def _frames(pile_factory, contacts_factory):
    pos, rad, fixed, row = pile_factory(4, 4)
    assert len(rad) == 18 and fixed[:4].all() and not fixed[4:].any()
    pair0 = contacts_factory(pos, rad, 4.0)
    c = len(pair0)
    f0 = np.column_stack([np.ones(c), np.zeros(c)])
    s0 = np.ones(c, np.int8)
    k89 = np.flatnonzero((pair0[:, 0] == 8) & (pair0[:, 1] == 9))[0]
    f1, s1 = f0.copy(), s0.copy()
    f1[k89] = [1.0, 0.5]
    s1[k89] = 2
    pos2 = pos.copy()
    pos2[15, 1] += 0.3
    keep = ~((pair0[:, 0] == 15) | (pair0[:, 1] == 15))
    f2, s2 = f0.copy(), s0.copy()
    f2[k89] = [0.0, 0.0]
    s2[k89] = 0
    perm = np.random.default_rng(0).permutation(np.flatnonzero(keep))
    vel1 = np.zeros((18, 2))
    vel1[12] = [1.0, 0.0]
    om1 = np.zeros(18)
    om1[12] = 2.0
    return dict(radius=rad, fixed=fixed, box_length=4.0, positions=[pos, pos, pos2],
                contacts=[(pair0, f0, s0), (pair0, f1, s1), (pair0[perm], f2[perm], s2[perm])],
                theta_deg=[0.0, 0.05, 0.10], velocities=[np.zeros((18, 2)), vel1, np.zeros((18, 2))],
                omegas=[np.zeros(18), om1, np.zeros(18)])


@pytest.fixture
def tiny_run(tmp_path, pile_factory, contacts_factory, run_writer):
    path = tmp_path / "run_0007.h5"
    run_writer(path, seed=7, **_frames(pile_factory, contacts_factory))
    return path


def test_run_observables_by_hand(tiny_run):
    fr, cl = ob.run_observables(tiny_run)
    assert list(fr.columns) == FRAME_COLUMNS and set(REQUIRED_FRAME) <= set(fr.columns)
    assert list(cl.columns) == CLUSTER_COLUMNS and set(REQUIRED_CLUSTER) <= set(cl.columns)
    assert fr["run"].tolist() == [7, 7, 7] and fr["frame"].tolist() == [0, 1, 2]
    assert fr["n_mobile"].tolist() == [14] * 3 and fr["n_bulk"].tolist() == [7] * 3
    # bulk z: row 2 = 4 + 6 + 6 + 4, row 3 = 5 + 6 + 5 -> 36 / 7; frame 2 loses 4 grain-contacts
    assert fr["z"].to_numpy() == pytest.approx([36 / 7, 36 / 7, 32 / 7])
    assert fr["n_m"].to_numpy() == pytest.approx([0.0, 1 / 7, 0.0])
    assert fr["dz_gen"].to_numpy() == pytest.approx([15 / 7, 2.0, 11 / 7])
    # all mobile grains: rows 1-4 = 16 + 20 + 16 + 14 = 66 contacts-ends over 14 grains
    assert fr["z_all"].iloc[0] == pytest.approx(66 / 14)
    # contacts with a mobile grain: 47 listed - 3 fixed-fixed - 4 fixed-floor - 2 fixed-wall
    assert fr["n_active"].tolist() == [38, 38, 33]
    assert fr["n_mobilized"].tolist() == [0, 1, 0]
    # lost: none 0 -> 1; (8,9) and grain 15's four contacts 1 -> 2; last frame undefined
    assert fr["n_lost"].tolist() == [0, 5, -1]
    assert fr["lost_fraction"].iloc[:2].tolist() == pytest.approx([0.0, 5 / 38])
    assert np.isnan(fr["lost_fraction"].iloc[2])
    assert fr["n_failing"].tolist() == [0, 7, -1]                 # 8, 9, 11, 12, 14, 15, 16
    assert fr["n_failing_in_cluster"].tolist() == [0, 2, -1]      # 8 and 9
    assert fr["failing_in_cluster_fraction"].iloc[1] == pytest.approx(2 / 7)
    # clusters
    assert fr["largest_cluster"].tolist() == [0, 2, 0]
    assert fr["n_clusters"].tolist() == [0, 1, 0]
    assert fr["cluster_fraction"].to_numpy() == pytest.approx([0.0, 2 / 14, 0.0])
    assert fr["z_rest"].iloc[1] == pytest.approx((4 + 4 + 5 + 6 + 5) / 5)
    # kinetic energy per mobile grain: m = pi/4, v = 1, I = m/8, omega = 2
    assert fr["ke_trans"].to_numpy() == pytest.approx([0.0, np.pi / 8 / 14, 0.0])
    assert fr["ke_rot"].to_numpy() == pytest.approx([0.0, np.pi / 16 / 14, 0.0])
    # avalanche: 5/38 > 2% at frame 1 -> onset 1; the NaN last frame stays in the avalanche
    assert fr["avalanching"].tolist() == [False, True, True]
    assert fr["onset"].tolist() == [False, True, False]
    assert fr["theta_to_onset"].to_numpy() == pytest.approx([-0.05, 0.0, 0.05])
    assert fr["max_displacement"].to_numpy() == pytest.approx([0.0, 0.0, 0.3])
    assert fr["mean_displacement"].to_numpy() == pytest.approx([0.0, 0.0, 0.3 / 14])
    assert fr["step"].tolist() == [0, 50, 100]
    # the one cluster: {8, 9}, z_i = 6, 6, one shared sliding contact, horizontal
    assert len(cl) == 1
    c = cl.iloc[0]
    assert (c["run"], c["frame"], c["cluster"], c["size"]) == (7, 1, 0, 2)
    assert (c["z"], c["n_m"], c["dz"]) == pytest.approx((6.0, 0.5, 5.5))
    assert c["orientation_deg"] == pytest.approx(90.0 - 0.05)
    assert c["theta_deg"] == pytest.approx(0.05) and bool(c["avalanching"])
    # orientation and speed are held to float32 precision (a record stores them in 4 bytes)
    for col in tables.FLOAT32_CLUSTER_COLUMNS:
        v = cl[col].to_numpy()
        assert v.dtype == np.float64 and np.array_equal(v.astype(np.float32).astype(float), v)
    assert c["orientation_deg"] != 90.0 - 0.05      # not a float32: rounded


def test_threshold_criterion_and_bulk_clusters(tiny_run):
    # with |f_t| >= mu f_n (1 - eps) the same (8, 9) contact is the only critical one
    fr, cl = ob.run_observables(tiny_run, eps=0.01, cluster_region="bulk", link="mobilized")
    assert fr["n_mobilized"].tolist() == [0, 1, 0]
    assert cl["size"].tolist() == [2]
    with pytest.raises(TypeError, match="unknown analysis parameter"):
        ob.run_observables(tiny_run, cutof=0.03)


def test_compute_and_load_are_cached_and_incremental(tiny_run, pile_factory, contacts_factory,
                                                     run_writer):
    d = tiny_run.parent
    with pytest.raises(FileNotFoundError, match="tiltpile observables"):
        load_observables(d, compute_missing=False)
    s1 = compute_observables(d, workers=1, progress=False)
    assert s1["status"].tolist() == ["computed"]
    assert (d / "observables" / "run_0007.npz").exists()
    s2 = compute_observables(d, workers=1, progress=False)
    assert s2["status"].tolist() == ["cached"]
    fr, cl = load_observables(d, compute_missing=False)
    direct, direct_cl = ob.run_observables(tiny_run)
    pd.testing.assert_frame_equal(fr, direct)
    pd.testing.assert_frame_equal(cl, direct_cl)
    # a second run appears; the first is touched (new mtime): both recomputed, nothing else
    run_writer(d / "run_0008.h5", seed=8, **_frames(pile_factory, contacts_factory))
    st = tiny_run.stat()
    os.utime(tiny_run, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    s3 = compute_observables(d, workers=1, progress=False)
    assert s3["status"].tolist() == ["computed", "computed"]
    assert compute_observables(d, workers=1, progress=False)["status"].tolist() == ["cached"] * 2
    # a cache of a column computed by other code, or lacking a column (one added since), is stale
    assert ob._read_meta(d / "observables" / "run_0007.npz")["columns"] == ob.column_code()
    real = ob.column_code
    other = real()
    other["frames"]["z"] = "0" * 16
    fewer = real()
    del fewer["clusters"]["speed_max"]
    try:
        for codes in (other, fewer):
            ob.column_code = lambda codes=codes: codes
            assert compute_observables(d, workers=1, progress=False)["status"].tolist() == ["computed"] * 2
    finally:
        ob.column_code = real
    assert compute_observables(d, workers=1, progress=False)["status"].tolist() == ["computed"] * 2
    # other analysis parameters are a different cache
    assert compute_observables(d, workers=1, progress=False, cutoff=0.2)["status"].tolist() == ["computed"] * 2
    fr, cl = load_observables(d, compute_missing=False, cutoff=0.2)
    assert fr["run"].tolist() == [7, 7, 7, 8, 8, 8]
    assert not fr["avalanching"].any()                    # 5/38 < 20%
    assert cl["run"].tolist() == [7, 8]


def test_parallel_compute(tmp_path, pile_factory, contacts_factory, run_writer):
    for seed in (1, 2):
        run_writer(tmp_path / f"run_{seed:04d}.h5", seed=seed, **_frames(pile_factory, contacts_factory))
    out = compute_observables(tmp_path, workers=2, progress=False)
    assert out["status"].tolist() == ["computed", "computed"]
    fr, _ = load_observables(tmp_path, compute_missing=False)
    assert fr.groupby("run")["z"].first().to_numpy() == pytest.approx([36 / 7, 36 / 7])


def test_empty_directory_is_an_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="no run_"):
        load_observables(tmp_path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        compute_observables(tmp_path / "nope")


def test_lost_gap_counts_only_contacts_that_open():
    # three grains in a row, touching: contacts (0,1) and (1,2) carry force at frame k. At k + 1
    # both carry no force; grain 2 has moved away by 0.01 d, grain 1 has not moved (its contact
    # with 0 only shed its load, as a hyperstatic rigid pile can without any motion).
    radius = np.full(3, 0.5)
    fixed = np.zeros(3, bool)
    pos_k = np.array([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0]])
    pos_k1 = pos_k + np.array([[0.0, 0.0], [0.0, 0.0], [0.01, 0.0]])
    pair = np.array([[0, 1], [1, 2]], np.int32)
    prev = {"pair": pair, "active": np.array([True, True]), "labels": np.full(3, -1), "position": pos_k}
    cur = {"pair": pair, "active": np.array([False, False]), "labels": np.full(3, -1), "position": pos_k1}
    by_force = ob.failure_between(prev, cur, fixed)
    assert by_force["n_lost"] == 2 and by_force["lost_fraction"] == 1.0
    by_gap = ob.failure_between(prev, cur, fixed, radius, 10.0, lost_gap=1e-3)
    assert by_gap["n_lost"] == 1 and by_gap["lost_fraction"] == 0.5 and by_gap["n_failing"] == 2
    assert ob.failure_between(prev, cur, fixed, radius, 10.0, lost_gap=0.02)["n_lost"] == 0
    with pytest.raises(ValueError, match="lost_gap"):
        ob._params({"lost_gap": -1.0})
