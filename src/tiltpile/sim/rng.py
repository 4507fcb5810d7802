"""A tiny xorshift64* generator for kernels, with its state in a (1,) uint64 array.

numba's built-in ``np.random`` keeps hidden per-thread state that cannot be saved; a run must
resume bit-identically from a checkpoint, so the state lives in an array the checkpoint holds.
Reference: S. Vigna, "An experimental exploration of Marsaglia's xorshift generators, scrambled",
ACM TOMS 42 (2016).
"""

import numpy as np

from tiltpile.sim.jit import njit


def make_state(seed: int) -> np.ndarray:
    """State array from a seed (splitmix64 scrambling so small seeds give unrelated streams)."""
    z = (int(seed) + 0x9E3779B97F4A7C15) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    z ^= z >> 31
    return np.array([z or 1], dtype=np.uint64)


@njit
def next_u64(state):
    x = state[0]
    x ^= x >> np.uint64(12)
    x ^= x << np.uint64(25)
    x ^= x >> np.uint64(27)
    state[0] = x
    return x * np.uint64(0x2545F4914F6CDD1D)


@njit
def below(state, n):
    """Integer uniform in [0, n) (n small against 2**64, so the modulo bias is negligible)."""
    return np.int64(next_u64(state) % np.uint64(n))


@njit
def shuffle(state, perm):
    """Fisher-Yates shuffle of ``perm`` in place."""
    for k in range(perm.shape[0] - 1, 0, -1):
        m = below(state, k + 1)
        t = perm[k]
        perm[k] = perm[m]
        perm[m] = t
