"""Fig. 7's numbers on hand-built tables whose answers are known (tiltpile.figures.fig7).

The pebble game itself is tested in tests/analysis/test_analysis_rigidity.py; the notebook on a
smoke ensemble, with its numbers locked, in test_notebooks.py.
"""

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from tiltpile.figures import data, fig7  # noqa: E402


def _run(run, theta, avalanching, spanning, rigid, dz=0.1):
    """A per-frame table of one run with theta_to_onset from its onsets (the first avalanching
    frame after a quiet one)."""
    theta = np.asarray(theta, float)
    av = np.asarray(avalanching, bool)
    onset = av & ~np.r_[False, av[:-1]]
    on_theta = theta[onset]
    nxt = np.full(theta.size, np.nan)
    for i, t in enumerate(theta):
        later = on_theta[on_theta > t] if not av[i] else on_theta[on_theta >= t]
        nxt[i] = later[0] if later.size else np.nan
    return pd.DataFrame({"run": run, "frame": np.arange(theta.size), "theta_deg": theta,
                         "avalanching": av, "onset": onset, "theta_m": nxt,
                         "theta_to_onset": theta - nxt, "rigid_spanning": np.asarray(spanning, bool),
                         "rigid_fraction": np.asarray(rigid, float),
                         "floppy_per_grain": 1.0 - np.asarray(rigid, float),
                         "dz_gen": np.full(theta.size, dz), "z": 3.5, "n_m": 0.2})


def test_onset_states_reads_the_last_quiet_frame_and_the_loss_before_it():
    # run 0: spans until 1.0 deg, loses it at 1.5 and 2.0, onset at 2.5 (and again at 4.0)
    f0 = _run(0, [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0],
              [0, 0, 0, 0, 0, 1, 0, 0, 1],
              [1, 1, 1, 0, 0, 0, 1, 1, 0],
              [1, 1, 1, .4, .3, .2, .9, .9, .1])
    on = fig7.onset_states(f0)
    assert on["theta_m"].tolist() == [2.5, 4.0]
    assert on["spanning_before"].tolist() == [False, True]
    assert on["spanning_at"].tolist() == [False, False]
    assert on["loss_to_onset"].iloc[0] == pytest.approx(1.5 - 2.5)
    assert np.isnan(on["loss_to_onset"].iloc[1])
    assert on["rigid_fraction_before"].tolist() == [0.3, 0.9]
    # an onset at the first frame has no quiet frame before it: not counted
    f1 = _run(1, [0.0, 0.5], [1, 1], [0, 0], [0.1, 0.1])
    assert fig7.onset_states(f1).empty


def test_window_means_and_where_spanning_is_lost():
    # spanning fraction of the windows falls linearly from 1 to 0 over the last 4 deg
    t = np.arange(-8.0, 0.0, 0.25) + 10.0            # onset at 10 deg
    span_prob = np.clip(-(t - 10.0) / 4.0, 0, 1)
    # four runs whose frames span while span_prob exceeds (r + 1/2) / 4: the fraction of spanning
    # frames at theta is span_prob, to a quarter
    runs = []
    for r in range(4):
        rows = _run(r, np.r_[t, 10.0], np.r_[np.zeros(t.size), 1],
                    np.r_[span_prob > (r + 0.5) / 4.0, False], np.r_[span_prob, 0.0])
        runs.append(rows)
    frames = pd.concat(runs, ignore_index=True)
    path = fig7.window_means(frames, lo=-8.0, width=1.0, min_frames=3)
    assert path["n_frames"].tolist() == [16] * 8
    assert path["rigid_fraction"].iloc[0] == pytest.approx(1.0)
    # the spanning fraction crosses 1/2 two degrees before the onset (interpolated)
    assert data.first_below(path, "spanning", 0.5) == pytest.approx(-2.0, abs=0.2)
    assert np.isnan(data.first_below(path.assign(spanning=1.0), "spanning", 0.5))
    assert np.isnan(data.first_below(path, "dz_gen", 0.0))          # dz_gen = 0.1 throughout
    assert data.first_below(path, "dz_gen", 0.2) == path["theta_to_onset"].iloc[0]


def test_compute_refuses_tables_without_the_rigidity_columns():
    class Ens:
        frames = _run(0, [0.0, 1.0], [0, 1], [1, 0], [1, 0]).drop(columns=["rigid_spanning"])
        seeds = [0]
    with pytest.raises(ValueError, match=r"lack \['rigid_spanning'\]: recompute"):
        fig7.compute(Ens(), snapshot=False)
