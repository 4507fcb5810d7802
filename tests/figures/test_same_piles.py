"""The same piles under two settings (tiltpile.figures.same_piles, ``tiltpile same-piles``).

The figure numbers it compares must be those ``make figures`` writes: on the session's smoke
ensemble, the documents it computes from the notebooks' own cells equal, key for key, the JSON the
notebook writes through papermill. The jackknife error of a mean is the standard error of the
mean; an ensemble against itself moves nothing, and a known shift is measured as that shift.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from tiltpile.figures import data
from tiltpile.figures import same_piles as sp
from tiltpile.figures import style

FAST = ("fig2_avalanche_criterion", "fig4_cluster_isostaticity")


@pytest.fixture(scope="module")
def ens(smoke_ensemble):
    return data.load(smoke_ensemble, "smoke", cutoff=0.02, lost_gap=None)


@pytest.mark.slow
@pytest.mark.parametrize("stem", FAST)
def test_documents_are_the_notebooks_json(stem, ens, smoke_ensemble, tmp_path):
    from test_notebooks import NOTEBOOK_DIR, execute
    execute(NOTEBOOK_DIR / f"{stem}.ipynb", smoke_ensemble, tmp_path)
    written = json.loads((tmp_path / f"{stem}.json").read_text())
    assert sp.figure_documents(ens, (stem,))[stem] == written


def raised_z(ens, dz=0.1):
    """``ens`` with every grain's z raised by ``dz``: a known shift of every z-derived number."""
    f = ens.frames.copy()
    f["z"] = f["z"] + dz
    return replace(ens, frames=f)


def test_jackknife_of_a_mean_is_its_standard_error():
    x = np.array([1.0, 4.0, 2.5, 7.0, 3.0])
    loo = [{"m": float(np.delete(x, i).mean())} for i in range(x.size)]
    se = sp.jackknife({"m": float(x.mean())}, loo)["m"]
    assert se == pytest.approx(x.std(ddof=1) / math.sqrt(x.size), rel=1e-12)
    # a number that one left-out run makes undefined has no error
    assert math.isnan(sp.jackknife({"m": 1.0}, loo[:-1] + [{"m": math.nan}])["m"])
    # values that differ by rounding only (0.45 summed in another order) have no spread: a shift
    # of one frame over an error of 3e-15 is not a move of 1.7e13 standard errors
    rounded = [{"m": 0.45}, {"m": 0.45000000000000284}, {"m": 0.45}, {"m": 0.45000000000000284}]
    assert sp.jackknife({"m": 0.45}, rounded)["m"] == 0.0
    assert math.isnan(sp._in_sigma(0.05, 0.0))                     # nothing to move by
    tiny = [{"m": 1e-8 * (1 + 1e-3 * i)} for i in range(4)]           # a real spread at 1e-8
    assert sp.jackknife({"m": 1e-8}, tiny)["m"] > 0.0


def test_subset_and_common_seeds(ens):
    sub = sp.subset(ens, ens.seeds[:2])
    assert sub.seeds == ens.seeds[:2] and set(sub.frames["run"]) == set(ens.seeds[:2])
    assert set(sub.clusters["run"]) <= set(ens.seeds[:2]) and sub.meta["n_runs"] == 2
    assert sp.common_seeds(ens, sub) == ens.seeds[:2]
    with pytest.raises(ValueError, match=r"seeds \[99\] are not in the ensemble"):
        sp.subset(ens, [99])


def test_an_ensemble_against_itself_moves_nothing(ens):
    table, na, nb = sp.ensemble_against_ensemble(ens, ens, FAST)
    assert na == nb and len(table) > 20
    assert (table["shift"].fillna(0.0) == 0.0).all() and not table["moved"].any()
    assert (table["sigma"].dropna() == 0.0).all()


def test_a_known_shift_is_measured(ens):
    """Every grain's z raised by 0.1: Fig. 2's <z> moves by 0.1 exactly, a number the shift does
    not touch (the first onsets) stays, and the paired error of a uniform shift is 0."""
    shifted = raised_z(ens)
    table, _, _ = sp.ensemble_against_ensemble(ens, shifted, ("fig2_avalanche_criterion",))
    t = table.set_index("key")
    assert t.loc["z_quiet_mean", "shift"] == pytest.approx(0.1, abs=1e-12)
    assert t.loc["z_quiet_mean", "se_paired"] == pytest.approx(0.0, abs=1e-12)
    assert t.loc["theta_m_mean", "shift"] == 0.0 and t.loc["theta_m_mean", "sigma"] == 0.0


def test_two_piles_are_compared_without_an_error(ens, tmp_path):
    """Two common seeds (two piles of an expensive setting): the shift is measured, no number has
    an error or moves, the pile-against-pile table has its two differences, chance's count is
    refused; one seed is refused."""
    two = sp.subset(ens, ens.seeds[:2])
    shifted = raised_z(two)
    table, na, _ = sp.ensemble_against_ensemble(two, shifted, ("fig2_avalanche_criterion",))
    t = table.set_index("key")
    assert t.loc["z_quiet_mean", "shift"] == pytest.approx(0.1, abs=1e-12)
    assert table["se"].isna().all() and table["se_ref"].isna().all() and not table["moved"].any()
    assert table.loc[table["shift"] != 0.0, "sigma"].isna().all()
    assert na["fig2_avalanche_criterion"]["n_runs"] == 2
    pp = sp.pile_against_pile(two, shifted, na["fig2_avalanche_criterion"]["numbers"],
                              na["fig2_avalanche_criterion"]["numbers"])
    assert pp["difference"]["z_quiet"]["n"] == 2
    assert pp["difference"]["z_quiet"]["mean"] == pytest.approx(0.1, abs=1e-12)
    with pytest.raises(ValueError, match="chance moves needs 3"):
        sp.null_moved(two, shifted, table, 2, stems=("fig2_avalanche_criterion",), scratch=tmp_path)
    one = sp.subset(ens, ens.seeds[:1])
    with pytest.raises(ValueError, match="share 1 seeds: the comparison needs 2"):
        sp.ensemble_against_ensemble(one, one, ("fig2_avalanche_criterion",))


def test_mixed_ensembles_exchange_the_runs_of_the_flipped_seeds(ens, tmp_path):
    """No flip gives the two ensembles back; a flip exchanges that seed's runs (and the run file
    its pictures read) and nothing else."""
    f = ens.frames.copy()
    f["z"] = f["z"] + 0.1
    other = replace(ens, frames=f)
    x, y = sp.mixed(ens, other, [False] * len(ens.seeds), tmp_path)
    pd_eq = lambda u, v: u.reset_index(drop=True).equals(v.reset_index(drop=True))  # noqa: E731
    assert pd_eq(x.frames, ens.frames) and pd_eq(y.frames, other.frames)
    flip = [k == 1 for k in range(len(ens.seeds))]
    x, y = sp.mixed(ens, other, flip, tmp_path)
    s = ens.seeds[1]
    for u, a, b in ((x, other, ens), (y, ens, other)):
        assert pd_eq(u.frames[u.frames["run"] == s], a.frames[a.frames["run"] == s])
        rest = u.frames[u.frames["run"] != s]
        assert pd_eq(rest, b.frames[b.frames["run"] != s])
        assert u.run_path(s).resolve() == ens.run_path(s).resolve()   # both sides' file here
    with pytest.raises(ValueError, match="flips"):
        sp.mixed(ens, other, [True], tmp_path)


def test_the_null_counts_what_chance_moves(ens, tmp_path):
    """An ensemble against itself: every exchange moves nothing, p = 1. Against a copy with every
    z raised by 0.1, the observed count is the largest there is (an exchange moves part of the
    shift back, or all of it to the other side), so no exchange exceeds it; the same generator
    seed gives the same exchanges."""
    table, _, _ = sp.ensemble_against_ensemble(ens, ens, FAST)
    null = sp.null_moved(ens, ens, table, 3, stems=FAST, scratch=tmp_path)
    assert null["counts"] == [0, 0, 0] and null["observed"] == 0 and null["p_value"] == 1.0
    f = ens.frames.copy()
    f["z"] = f["z"] + 0.1
    shifted = replace(ens, frames=f)
    table, _, _ = sp.ensemble_against_ensemble(ens, shifted, ("fig2_avalanche_criterion",))
    null = sp.null_moved(ens, shifted, table, 6, stems=("fig2_avalanche_criterion",),
                         scratch=tmp_path)
    assert null["observed"] > 0 and len(null["counts"]) == 6
    assert max(null["counts"]) <= null["observed"]
    assert null == sp.null_moved(ens, shifted, table, 6, stems=("fig2_avalanche_criterion",),
                                 scratch=tmp_path)        # the same flips: the same counts
    with pytest.raises(ValueError, match="flips"):
        sp.null_moved(ens, ens, table, 0)


def test_workers_compute_the_same_study(ens, tmp_path):
    """Figures evaluated in two processes give the study of one, bit for bit: the table, both
    sides' documents and chance's counts (each exchange's run-file links in its own folder), and
    the progress lines in the same order."""
    f = ens.frames.copy()
    f["z"] = f["z"] + 0.05
    shifted = replace(ens, frames=f)
    lines, docs = {1: [], 2: []}, {}
    for w in (1, 2):
        table, na, nb = sp.ensemble_against_ensemble(ens, shifted, FAST, progress=lines[w].append,
                                                     workers=w)
        null = sp.null_moved(ens, shifted, table, "exact", stems=FAST, scratch=tmp_path / str(w),
                             progress=lines[w].append, workers=w)
        docs[w] = json.dumps(style.jsonable([table.to_dict("records"), na, nb, null]),
                             sort_keys=True)
    assert docs[1] == docs[2] and null["flips"] == 4 and null["observed"] > 0
    assert lines[1] == lines[2] and sum("null: flip" in x for x in lines[2]) == 4
    assert {p.name for p in (tmp_path / "2").iterdir()} == {"flip0", "flip1", "flip2", "flip3"}
    with pytest.raises(ValueError, match="workers must be at least 1"):
        next(sp.documents_each([("x", ens)], FAST, workers=0))


def test_worker_processes_run_one_blas_thread_and_leave_the_callers_environment(monkeypatch):
    """Each worker starts with one BLAS thread (W workers with the threads of one process each
    oversubscribe W cores), and the caller's environment is restored, unset keys unset."""
    import os

    from tiltpile.ensemble import WORKER_ENV
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    with sp.worker_pool(2) as pool:
        seen = {k: pool.submit(os.getenv, k).result() for k in WORKER_ENV}
    assert seen == WORKER_ENV
    assert "OPENBLAS_NUM_THREADS" not in os.environ and os.environ["OMP_NUM_THREADS"] == "3"


def test_pile_against_pile(ens):
    docs = sp.figure_documents(ens, ("fig2_avalanche_criterion",))
    n2 = docs["fig2_avalanche_criterion"]["numbers"]
    f = ens.frames.copy()
    f["z"] = f["z"] + 0.25
    pp = sp.pile_against_pile(ens, replace(ens, frames=f), n2, n2)
    assert pp["seeds"] == list(ens.seeds)
    assert pp["difference"]["z_quiet"]["mean"] == pytest.approx(0.25, abs=1e-12)
    assert pp["difference"]["z_start"]["mean"] == pytest.approx(0.25, abs=1e-12)
    assert all(d == 0.0 for d in pp["per_seed"]["n_onsets"]["difference"])
    assert set(pp["per_seed"]) == set(sp.PER_SEED)
    assert pp["difference"]["ke_quiet"]["mean"] == 0.0
    # a shift the same on every seed has no spread: the smallest detectable shift is ~0
    assert pp["difference"]["z_quiet"]["sd"] == pytest.approx(0.0, abs=1e-12)
    assert pp["difference"]["n_onsets"]["min_detectable"] == 0.0


def test_quiet_kinetic_energy_is_the_median_over_quiet_frames_only(ens):
    """Translational plus rotational, over the frames not avalanching: raising the kinetic energy
    of the avalanching frames leaves it, doubling every frame's doubles it."""
    f = ens.frames
    base = sp.quiet_kinetic_energy(f, ens.seeds)
    s0 = ens.seeds[0]
    g = f[(f["run"] == s0) & ~f["avalanching"].astype(bool)]
    assert base[0] == pytest.approx(float(np.median(g["ke_trans"] + g["ke_rot"])), rel=1e-15)
    loud = f.copy()
    loud.loc[loud["avalanching"].astype(bool), "ke_trans"] += 1.0
    assert np.array_equal(sp.quiet_kinetic_energy(loud, ens.seeds), base, equal_nan=True)
    double = f.copy()
    double[["ke_trans", "ke_rot"]] *= 2.0
    assert np.allclose(sp.quiet_kinetic_energy(double, ens.seeds), 2.0 * base, rtol=1e-15, equal_nan=True)
    assert np.isfinite(base).all() and (base > 0).all()


def test_command_refuses_bad_input(smoke_ensemble, tmp_path, capsys):
    from tiltpile.cli import main
    out = tmp_path / "cmp"
    assert main(["same-piles", str(smoke_ensemble), str(smoke_ensemble), "--out", str(out)]) == 2
    assert "REF and DIR are the same directory" in capsys.readouterr().err
    assert main(["same-piles", str(tmp_path / "nope"), str(smoke_ensemble), "--out", str(out)]) == 2
    assert "no such ensemble directory" in capsys.readouterr().err
    assert main(["same-piles", str(smoke_ensemble), str(tmp_path), "--out", str(out),
                 "--seeds", "1"]) == 2
    assert "--seeds must be at least 2, got 1" in capsys.readouterr().err
    two = tmp_path / "two"
    two.mkdir()
    for run in sorted(smoke_ensemble.glob("run_*.h5"))[:2]:
        (two / run.name).symlink_to(run.resolve())
    assert main(["same-piles", str(smoke_ensemble), str(two), "--out", str(out), "--null", "3",
                 "--label", "two", "--quiet"]) == 2
    assert "--null 3: on 2 seeds no figure number has an error" in capsys.readouterr().err
    assert main(["same-piles", str(smoke_ensemble), str(two), "--out", str(out), "--workers",
                 "0", "--label", "two"]) == 2
    assert "--workers must be 1 or more, got 0" in capsys.readouterr().err
    assert not out.exists()


# ----------------------------------------------------------------------------------------------
# the null: exact enumeration, its Monte-Carlo error, the decision as data


def test_exact_flips_are_every_distinct_exchange():
    """2^(n - 1) exchanges, the first seed never exchanged, the first one none at all; with
    their complements, every one of the 2^n exactly once."""
    flips = sp.exact_flips(4)
    assert len(flips) == 8 and not any(f[0] for f in flips) and not flips[0].any()
    both = {tuple(bool(v) for v in f) for f in flips} | {tuple(bool(v) for v in ~f) for f in flips}
    assert len(both) == 16
    assert sp.canonical([True, False, True, True]) == (False, True, False, False)
    assert all(sp.canonical(f) == sp.canonical(~f) for f in sp.random_flips(5, 20))
    assert len(sp.exact_flips(1)) == 1
    with pytest.raises(ValueError, match="no exchange of 0 seeds"):
        sp.exact_flips(0)
    # the random draws of the committed 40 are the first 40 of 500
    assert all((u == v).all() for u, v in zip(sp.random_flips(16, 40), sp.random_flips(16, 500)))


def test_null_plan():
    """auto: exact up to 256 exchanges (9 seeds), else 500 random; exact refused above 4096
    exchanges; a number of flips must be a positive integer."""
    assert sp.null_plan("auto", 8) == ("exact", 128)
    assert sp.null_plan("auto", 9) == ("exact", 256)
    assert sp.null_plan("auto", 10) == ("random", 500)
    assert sp.null_plan("auto", 16) == ("random", 500)
    assert sp.null_plan("exact", 13) == ("exact", 4096)
    assert sp.null_plan(40, 16) == ("random", 40)
    with pytest.raises(ValueError, match="more than 4096: give a number of random ones"):
        sp.null_plan("exact", 14)
    with pytest.raises(ValueError, match="flips must be at least 1, got 0"):
        sp.null_plan(0, 8)
    for bad in ("all", True, 2.5, None):
        with pytest.raises(ValueError, match="'exact', 'auto' or a number"):
            sp.null_plan(bad, 8)


def test_monte_carlo_error_and_the_decision():
    """sqrt(p (1 - p) / K): 0.034 from the committed 40 exchanges at p = 0.049, below 0.01 from
    500 on; p < 0.05 is "moved", else "no difference detected", firm when p is more than two
    Monte-Carlo errors from 0.05."""
    assert sp.mc_error(2 / 41, 40) == pytest.approx(0.0341, abs=5e-4)
    assert sp.mc_error(0.05, 500) == pytest.approx(math.sqrt(0.05 * 0.95 / 500), rel=1e-15)
    assert sp.mc_error(0.05, sp.RANDOM_FLIPS) < sp.MC_ERROR_LIMIT < sp.mc_error(0.05, 400)
    assert sp.decide(2 / 41, sp.mc_error(2 / 41, 40)) == {
        "alpha": 0.05, "decision": "moved", "decision_firm": False}
    assert sp.decide(0.05, 0.0)["decision"] == "no difference detected"
    assert sp.decide(6 / 128, 0.0) == {"alpha": 0.05, "decision": "moved", "decision_firm": True}
    assert sp.decide(0.24, sp.mc_error(0.24, 500))["decision_firm"]


def test_min_detectable():
    """(z_0.975 + z_0.8) sd / sqrt(n) = 2.80 sd / sqrt(n) over the finite differences; NaN for
    fewer than two."""
    assert sp.Z_DETECT == pytest.approx(1.959964 + 0.841621, abs=1e-6)
    d = [0.5, -1.0, 2.0, 1.5, np.nan]
    sd, mdd = sp.min_detectable(d)
    assert sd == pytest.approx(np.std([0.5, -1.0, 2.0, 1.5], ddof=1), rel=1e-15)
    assert mdd == pytest.approx(2.801585 * sd / 2.0, rel=1e-6)
    assert all(math.isnan(v) for v in sp.min_detectable([1.0, np.nan]))


def test_the_table_gives_the_smallest_detectable_shift(ens):
    """Per figure number (SIGMA_LIMIT + z_0.8) times its combined error: 2.84 of them."""
    table, _, _ = sp.ensemble_against_ensemble(ens, raised_z(ens), ("fig2_avalanche_criterion",))
    comb = np.hypot(table["se_ref"], table["se"])
    assert np.allclose(table["min_detectable"], 2.8416212335729144 * comb, rtol=1e-15,
                       equal_nan=True)
    assert np.isfinite(table["min_detectable"]).any()


def unevenly_shifted(ens):
    """``ens`` with seed-dependent shifts of z and n_m: exchanges move different numbers."""
    f = ens.frames.copy()
    for k, s in enumerate(ens.seeds):
        run = f["run"] == s
        f.loc[run, "z"] += 0.05 * (k + 1)
        f.loc[run, "n_m"] -= 0.01 * (len(ens.seeds) - k)
    return replace(ens, frames=f)


def test_a_flip_and_its_complement_count_alike(ens, tmp_path):
    """Exchanging the complement gives the same two ensembles in the other order: the same
    documents swapped, so the same count, for every exchange of the 3 smoke seeds."""
    other = unevenly_shifted(ens)
    stems = ("fig2_avalanche_criterion",)
    table, _, _ = sp.ensemble_against_ensemble(ens, other, stems)
    comb = {f"{r['figure']}.{r['key']}": math.hypot(r["se_ref"], r["se"])
            for r in table.to_dict("records")}
    counts = set()
    for f in sp.exact_flips(len(ens.seeds)):
        x, y = sp.mixed(ens, other, f, tmp_path / "f")
        xc, yc = sp.mixed(ens, other, ~f, tmp_path / "c")
        assert xc.frames.equals(y.frames) and yc.frames.equals(x.frames)
        dx, dy = (sp._all_scalars(sp.figure_documents(e, stems)) for e in (x, y))
        dxc, dyc = (sp._all_scalars(sp.figure_documents(e, stems)) for e in (xc, yc))
        assert json.dumps(dxc) == json.dumps(dy) and json.dumps(dyc) == json.dumps(dx)
        n = sp.moved_count(dx, dy, comb)
        assert sp.moved_count(dxc, dyc, comb) == n
        counts.add(n)
    assert len(counts) > 1          # the exchanges do differ


def test_the_exact_null(ens, tmp_path):
    """All 4 distinct exchanges of 3 seeds, each evaluated once, the first the real pair (its
    count the observed one); p = #(count >= observed) / 4 with no Monte-Carlo error; random
    draws reuse the count of the exchange they repeat (or its complement)."""
    other = unevenly_shifted(ens)
    stems = ("fig2_avalanche_criterion",)
    table, _, _ = sp.ensemble_against_ensemble(ens, other, stems)
    lines = []
    null = sp.null_moved(ens, other, table, "exact", stems=stems, scratch=tmp_path / "x",
                         progress=lines.append)
    assert null["method"] == "exact" and null["flips"] == null["evaluated"] == 4
    assert null["seed"] is None and null["mc_error"] == 0.0
    c = np.array(null["counts"])
    assert c[0] == null["observed"] == int(table["moved"].sum()) > 0
    assert null["p_value"] == (c >= null["observed"]).sum() / 4
    assert null["decision"] == ("moved" if null["p_value"] < 0.05 else "no difference detected")
    assert null["decision_firm"] and sum("null: flip" in x for x in lines) == 4
    assert sp.null_moved(ens, other, table, "auto", stems=stems, scratch=tmp_path / "a") == null
    by_flip = {sp.canonical(f): n for f, n in zip(sp.exact_flips(3), null["counts"])}
    rnd = sp.null_moved(ens, other, table, 9, stems=stems, scratch=tmp_path / "r")
    assert rnd["method"] == "random" and rnd["flips"] == 9 and rnd["evaluated"] <= 4
    assert rnd["counts"] == [by_flip[sp.canonical(f)] for f in sp.random_flips(3, 9)]
    p = (1 + sum(n >= rnd["observed"] for n in rnd["counts"])) / 10
    assert rnd["p_value"] == p and rnd["mc_error"] == pytest.approx(math.sqrt(p * (1 - p) / 9))


def test_memoized_fits_give_the_same_documents(ens):
    """Fig. 5 with its fits memoized: the same documents, bit for bit, a second evaluation
    computes no fit anew, and the figures' own function is back after the block."""
    from tiltpile.figures import fig5
    real = fig5._fit
    stems = ("fig5_cluster_sizes",)
    plain = sp.figure_documents(ens, stems)
    with sp.fit_memo():
        assert fig5._fit is not real
        first = sp.figure_documents(ens, stems)
        held = len(sp._FIT_CACHE)
        with sp.fit_memo():                       # nested: the same memo
            again = sp.figure_documents(ens, stems)
        assert held > 0 and len(sp._FIT_CACHE) == held and fig5._fit is not real
    assert fig5._fit is real and sp._FIT_CACHE is None
    assert json.dumps(first, sort_keys=True) == json.dumps(plain, sort_keys=True)
    assert json.dumps(again, sort_keys=True) == json.dumps(plain, sort_keys=True)


def test_null_values_are_checked_before_anything_runs(smoke_ensemble, tmp_path, capsys):
    from tiltpile.cli import main
    from tiltpile.cli._common import ConfigError
    from tiltpile.cli.same_piles import null_spec
    assert [null_spec(v) for v in ("none", "0", "exact", "AUTO", "500")] == [
        None, None, "exact", "auto", 500]
    out = tmp_path / "cmp"
    for bad in ("-3", "all", "2.5", ""):
        with pytest.raises(ConfigError, match="--null must be exact, auto, none or a number"):
            null_spec(bad)
        assert main(["same-piles", str(tmp_path / "nope"), str(smoke_ensemble), "--out", str(out),
                     "--null", bad]) == 2
        err = capsys.readouterr().err.strip()
        assert "--null must be exact, auto, none or a number" in err and "\n" not in err
    assert not out.exists()


def test_a_run_without_the_event_is_censored_at_the_end_of_its_tilt_not_left_out():
    """The DEM's first onset at 20.45 deg where CD has none by 22 deg: the pair's difference is at
    most 20.45 - 22, and the mean over all pairs is an upper bound; none censored: None."""
    import math

    from tiltpile.figures.same_piles import censored_difference

    nan = math.nan
    x = [nan, 19.65, 19.4, 13.0, 19.25, 17.25]
    y = [20.45, 17.3, 20.3, 19.1, 21.8, 17.05]
    c = censored_difference(x, y, [22.0] * 6, [22.0] * 6)
    d = [20.45 - 22.0] + [b - a for a, b in zip(x[1:], y[1:])]
    assert c["n_censored"] == 1 and c["bound"] == "at most" and c["n"] == 6
    assert c["mean"] == pytest.approx(sum(d) / 6) and c["ci_low"] <= c["mean"] <= c["ci_high"]
    low = censored_difference([10.0, 11.0, 12.0], [nan, 12.0, 13.0], [22.0] * 3, [21.0] * 3)
    assert low["bound"] == "at least" and low["mean"] == pytest.approx((11.0 + 1.0 + 1.0) / 3)
    both = censored_difference([nan, 11.0, 12.0], [10.0, nan, 13.0], [22.0] * 3, [21.0] * 3)
    assert both["bound"] == "mixed" and both["n_censored"] == 2
    assert censored_difference([10.0, nan], [11.0, nan], [22.0] * 2, [22.0] * 2) is None
