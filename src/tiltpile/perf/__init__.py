"""Solver measurements behind the numbers quoted in sim/solver.py, sim/jit.py and config.py.

Run as scripts: ``python -m tiltpile.perf.solver_variants N STEPS [EVAL_EVERY] [variant ...]`` and
``python -m tiltpile.perf.solver_micro N SWEEPS REPEATS``.
"""
