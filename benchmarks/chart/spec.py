"""What the speed x accuracy chart measures (:class:`ChartSpec`), its table columns, and the piles
it starts from. The chart itself: :mod:`benchmarks.chart`."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile.analysis.observables import DEFAULT_PARAMS
from tiltpile.sim import protocol
from tiltpile.sim.step import System

SETTLE_STEPS = 50           # steps at theta = 0 at the point's own setting before the tilt
CUTOFF = DEFAULT_PARAMS["cutoff"]  # avalanche criterion on the lost-contact fraction
# the simulator's defaults, highlighted in the chart
DEFAULT_TOL, DEFAULT_DT = cfgmod.SolverConfig().tol, cfgmod.SolverConfig().dt
DEFAULT_SLOP = cfgmod.SolverConfig().overlap_slop

ACCURACY_COLUMNS = [
    "seed", "tol", "dt", "slop", "is_default", "is_reference", "n_grains", "contacts",
    "ms_per_deg", "ms_per_deg_mean", "ms_per_step", "sweeps_mean", "sweeps_median", "cap_hit_fraction",
    "residual_median", "max_overlap", "theta_end", "steps", "wall_s",
    "theta_m", "z_quiet", "n_m_quiet", "quiet_frames", "drift_per_deg",
    "creep_mean", "creep_median", "creep_max", "creep_steps", "creep_max_overlap",
    "theta_m_shift", "z_shift", "n_m_shift", "resolution_warning",
]
SCALING_COLUMNS = [
    "n", "copies", "box_length", "sweep", "relax", "slop", "tol", "steps", "contacts", "active_contacts",
    "ms_per_step", "ms_per_step_mean", "ns_per_update", "sweeps_mean", "sweeps_median", "cap_hits",
    "settle_s", "fixed_sweeps",
]


@dataclass(frozen=True)
class ChartSpec:
    """What the chart measures; ``full()`` is ``make bench``, ``quick()`` the test's tiny version."""

    seeds: tuple = (3, 1)
    tols: tuple = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
    dts: tuple = (0.005, 0.01, 0.02)
    # the overlap slop (solver.overlap_slop): 0 is the plain gap term b = g / dt
    slops: tuple = (0.0, 1e-6, 1e-5)
    # "full": every (tol, dt, slop); "cross": each of the three varied alone, the other two at
    # their defaults (the full (tol, dt) grid on 2 seeds took ~20 min for the accuracy part
    # alone: points at tol <= 1e-5 tilt to 14-15 deg at ~500 sweeps per step, 90-100 s each)
    grid: str = "cross"
    scene: tuple = ("scene.n=250", "scene.box_length=20.0")  # on the smoke preset
    max_iter: int = 1000
    tilt_per_step: float = 0.001
    frame_every: int = 50
    theta_cap: float = 20.0
    margin_deg: float = 0.5
    hold_deg: float = 10.0
    creep_tilt_steps: int = 500
    creep_settle_time: float = 2.0
    creep_hold_time: float = 10.0
    base_n: int = 500
    copies: tuple = (1, 2, 4, 8, 16, 32)
    tile_settle_steps: int = 300
    scaling_tol: float = 1e-6
    scaling_steps: int = 100
    scaling_steps_large: int = 50   # for n > 4000
    variant_ns: tuple = (1000, 4000)
    variant_steps: int = 50
    fixed_sweeps: int = 100         # scaling at a fixed number of sweeps per step (tol 0)
    fixed_steps: int = 10
    # rounds of the fixed-sweep timing, each over every N in turn, so that a slow spell of the
    # shared machine falls on all N alike (one round of 10 steps per N gave per-grain spreads of
    # 1.41-1.76x from chart to chart)
    fixed_rounds: int = 5
    cache: str | None = "data/bench"
    quick: bool = False

    @classmethod
    def full(cls) -> "ChartSpec":
        return cls()

    @classmethod
    def quick_spec(cls) -> "ChartSpec":
        return cls(seeds=(3,), tols=(1e-2, 1e-4, 1e-6), dts=(0.01, 0.02), slops=(0.0, 1e-6),
                   scene=("scene.n=60", "scene.box_length=8.0"), theta_cap=3.0, margin_deg=0.2,
                   hold_deg=5.0, creep_tilt_steps=500, creep_settle_time=2.0, creep_hold_time=2.0,
                   base_n=60, copies=(1, 2), tile_settle_steps=50, scaling_steps=10,
                   scaling_steps_large=10, variant_ns=(120,), variant_steps=10, cache=None,
                   fixed_sweeps=20, fixed_steps=3, fixed_rounds=2,
                   grid="full", quick=True)


# ----------------------------------------------------------------------------------------------
# the points of the accuracy grid and the piles


def accuracy_config(spec: ChartSpec) -> cfgmod.Config:
    return cfgmod.load("smoke", None, [*spec.scene, f"solver.tol={min(spec.tols)!r}",
                                       f"solver.dt={min(spec.dts)!r}", f"solver.max_iter={spec.max_iter}",
                                       f"protocol.tilt_per_step_deg={spec.tilt_per_step!r}",
                                       f"protocol.frame_every={spec.frame_every}"])


def grid_points(spec: ChartSpec) -> list[tuple[float, float, float]]:
    """The (tol, dt, slop) points of the sweep, by slop, dt, then tol (``ChartSpec.grid``)."""
    pts = [(t, d, s) for s in spec.slops for d in spec.dts for t in spec.tols]
    if spec.grid == "cross":
        pts = [p for p in pts if sum(v != dv for v, dv in zip(p, (DEFAULT_TOL, DEFAULT_DT, DEFAULT_SLOP))) <= 1]
    elif spec.grid != "full":
        raise ValueError(f"grid must be 'full' or 'cross', got {spec.grid!r}")
    return pts


def copy_system(sysm: System) -> System:
    other = System.__new__(System)
    other.params = dict(sysm.params)
    other.restore(sysm.state())
    return other


def starting_pile(cfg: cfgmod.Config, seed: int, cache: str | None) -> System:
    """A deposited pile for ``cfg`` (cached under ``cache`` when given, :mod:`benchmarks.pile`)."""
    if cache is None:
        return protocol.deposited(cfg, seed)
    from benchmarks.pile import settled_pile
    return settled_pile(cfg, seed, progress=False, cache=Path(cache))


def log(msg: str, progress: bool) -> None:
    """A progress line on stderr when ``progress``."""
    if progress:
        print(msg, file=sys.stderr, flush=True)
