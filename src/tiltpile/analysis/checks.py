"""The inputs of the public analysis functions, checked: one line naming the argument.

Every public function of :mod:`tiltpile.analysis` (and of :mod:`tiltpile.analysis.stats`)
checks what a caller can get wrong before it computes -- a shape, a length that must match
another argument's, a contact index out of range, NaN where none is allowed, a negative radius,
a DataFrame without a column it reads, a parameter out of its range -- and refuses it with a
``ValueError`` (a value or shape) or a ``TypeError`` (a type: text for a number, a float array of
indices, a list for a DataFrame) whose message is one line (:class:`InputValueError`,
:class:`InputTypeError`, subclasses of those two):
``"<function>: <argument> must <what>, got <what it was>"``. These functions only raise: an input
they admit is computed exactly as before (what they convert, they convert for the check only).

The checks are vectorized (a shape, one reduction or two per array, no loop over elements). The
tables' engine checks a run's grains once and each frame's arrays once, then calls the functions'
unchecked cores (``_contact_counts``, ...), so that the checks cost under 1% of a frame's
computation (docs/architecture.md, "Analysis inputs").
"""

from __future__ import annotations

import math
from numbers import Integral as _Integral

import numpy as np

_NUMERIC = "biuf"      # dtype kinds that hold numbers (bool included: True is 1)
_INTEGER = "iu"
_PLAIN = (float, int, np.float64, np.float32, np.int64, np.int32)  # numbers, no questions


class InputValueError(ValueError):
    """An argument of a public analysis function has a wrong value or shape (one line)."""


class InputTypeError(TypeError):
    """An argument of a public analysis function has a wrong type (one line)."""


def short(x, width: int = 60) -> str:
    """A one-line repr of ``x``, at most ``width`` characters (an array: its shape and dtype)."""
    if isinstance(x, np.ndarray):
        return f"an array of shape {x.shape} and dtype {x.dtype}"
    r = " ".join(repr(x).split())
    return r if len(r) <= width else r[:width - 3] + "..."


def kind_of(x) -> str:
    """``x``'s type and :func:`short` repr, for a message (an array: its shape and dtype)."""
    return short(x) if isinstance(x, np.ndarray) else f"{type(x).__name__} {short(x)}"


def fail(fn: str, name: str, what: str, got: str, exc=ValueError):
    """Raise ``"<fn>: <name> must <what>, got <got>"`` (one line) as an :class:`InputValueError`
    (``exc`` ValueError) or :class:`InputTypeError` (``exc`` TypeError)."""
    cls = InputTypeError if issubclass(exc, TypeError) else InputValueError
    raise cls(" ".join(f"{fn}: {name} must {what}, got {got}".split()))


def asarray(fn: str, name: str, x, kinds: str = _NUMERIC) -> np.ndarray:
    """``x`` as an array (``x`` itself when it is one) whose dtype is of ``kinds``; TypeError
    for anything else (text, objects, ragged lists). Numbers wanted (``kinds`` with "f"): a list
    the functions convert to floats is admitted as such (None is NaN, as ``np.asarray(x,
    dtype=float)`` has it)."""
    if type(x) is np.ndarray:
        a = x
    else:
        try:
            a = np.asarray(x)
        except (TypeError, ValueError):
            fail(fn, name, "be an array of numbers", kind_of(x), TypeError)
    if a.dtype.kind in kinds or not a.size:     # an empty array holds nothing wrong
        return a
    if a.dtype.kind == "O" and "f" in kinds:
        try:
            return np.asarray(x, dtype=float)
        except (TypeError, ValueError):
            pass
    what = "hold integers" if kinds == _INTEGER else "hold numbers"
    fail(fn, name, what, f"dtype {a.dtype}" if a.dtype.kind != "O" else kind_of(x), TypeError)


def _shape(dims) -> str:
    return "(" + ", ".join(str(d) for d in dims) + ("," if len(dims) == 1 else "") + ")"


def shaped(fn: str, name: str, x, dims: tuple, like: str = "", *, finite: bool = False,
           kinds: str = _NUMERIC, empty_ok: bool = False) -> np.ndarray:
    """``x`` as an array of shape ``dims`` (ints; a str names a free dimension, e.g. "N"),
    ``like`` the argument the sizes come from (for the message, e.g. "radius (N=250)");
    ``finite``: no NaN or inf; ``empty_ok``: any empty array when the first size is 0 (an empty
    contact list, which the functions take in any shape)."""
    a = asarray(fn, name, x, kinds)
    if empty_ok and a.size == 0 and (isinstance(dims[0], str) or dims[0] == 0):
        return a
    ok = a.ndim == len(dims) and all(isinstance(d, str) or s == d for s, d in zip(a.shape, dims))
    if not ok:
        want = _shape(dims)
        fail(fn, name, f"have shape {want}" + (f" like {like}" if like else ""), str(a.shape))
    if finite and a.size and not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        at = int(bad[0]) if bad.size == 1 else tuple(int(b) for b in bad)
        fail(fn, name, "be finite (no NaN or inf)", f"{a[tuple(bad)]} at index {at}")
    return a


def boolean(fn: str, name: str, x, n: int | None, like: str = "", *,
            empty_ok: bool = False) -> np.ndarray:
    """``x`` as a (n,) mask (n None: any length): bool, or numbers that are all 0 or 1."""
    a = shaped(fn, name, x, ("N",) if n is None else (n,), like, kinds=_NUMERIC + "O",
               empty_ok=empty_ok)
    if a.dtype != bool and a.size:
        try:
            ok = bool((a.astype(bool) == a).all())
        except (TypeError, ValueError):
            ok = False
        if not ok:
            fail(fn, name, "be a boolean mask (True/False or 0/1)", f"dtype {a.dtype}")
    return a


def contact_pairs(fn: str, name: str, x, n: int | None = None, like: str = "") -> int:
    """``x`` a contact list (C, 2) of integers, i = x[:, 0] a grain in [0, n), j = x[:, 1] a grain
    in [0, n) or a wall (-1, -2, -3); an empty integer array of any shape is an empty list.
    Returns C."""
    a = asarray(fn, name, x)
    if a.dtype.kind not in _INTEGER:
        empty = " (no contacts: np.empty((0, 2), dtype=int))" if a.size == 0 else ""
        fail(fn, name, f"hold integers (grain indices; walls -1, -2, -3){empty}",
             f"dtype {a.dtype}", TypeError)
    if a.size == 0:
        return 0
    if a.ndim != 2 or a.shape[1] != 2:
        fail(fn, name, "have shape (C, 2) (grain i, grain or wall j per contact)", str(a.shape))
    if n is not None and not (a.min() >= -3 and a.max() < n and a[:, 0].min() >= 0):
        src = f" ({like})" if like else ""
        fail(fn, name, f"hold grain indices in [0, {n}){src} and, as j, walls -1, -2, -3",
             f"i in [{a[:, 0].min()}, {a[:, 0].max()}], j in [{a[:, 1].min()}, {a[:, 1].max()}]")
    return int(a.shape[0])


def count(fn: str, name: str, x, lo: int = 0, *, floats_ok: bool = False) -> int:
    """``x`` an integer >= ``lo`` (Python or numpy, not bool; ``floats_ok``: a float with a whole
    value too, 5.0, for a parameter the function computes with as a number); returns it as int."""
    if type(x) is not int and (isinstance(x, (bool, np.bool_))
                               or not isinstance(x, (_Integral, np.integer))):
        whole = (floats_ok and isinstance(x, (float, np.floating)) and math.isfinite(x)
                 and float(x).is_integer())
        if not whole:
            fail(fn, name, f"be an integer >= {lo}", kind_of(x), TypeError)
    if x < lo:
        fail(fn, name, f"be an integer >= {lo}", repr(x))
    return int(x)


def real(fn: str, name: str, x, *, lo=None, hi=None, lo_open: bool = False,
         hi_open: bool = False, nonfinite_ok: bool = False, none_ok: bool = False) -> None:
    """``x`` a real number (Python, numpy, or a 0-d array; not bool, not text) in the range
    [lo, hi] (``lo_open``/``hi_open``: exclusive); ``nonfinite_ok``: NaN and +-inf too (where the
    function gives NaN for them), outside the range check; ``none_ok``: None too."""
    if x is None and none_ok:
        return
    if type(x) in _PLAIN:
        v = float(x)
    else:
        if isinstance(x, (bool, np.bool_, str, bytes)) or np.ndim(x) != 0:
            fail(fn, name, "be a number", kind_of(x), TypeError)
        try:
            v = float(x)
        except (TypeError, ValueError):
            fail(fn, name, "be a number", kind_of(x), TypeError)
    if not math.isfinite(v):
        if nonfinite_ok:
            return
        fail(fn, name, "be a finite number", repr(v))
    low = lo is not None and (v <= lo if lo_open else v < lo)
    high = hi is not None and (v >= hi if hi_open else v > hi)
    if low or high:
        a = "(" if lo_open else "["
        b = ")" if hi_open else "]"
        rng = (f"in {a}{lo}, {hi}{b}" if lo is not None and hi is not None
               else f"{'>' if lo_open else '>='} {lo}" if lo is not None
               else f"{'<' if hi_open else '<='} {hi}")
        fail(fn, name, f"be {rng}", repr(v))


def radii(fn: str, x, name: str = "radius") -> np.ndarray:
    """``x`` the grains' radii: (N,), finite and > 0."""
    a = shaped(fn, name, x, ("N",), finite=True)
    if a.size and not (a > 0).all():
        k = int(np.flatnonzero(~(a > 0))[0])
        fail(fn, name, "be > 0 (d)", f"{a[k]} at index {k}")
    return a


def statuses(fn: str, name: str, x, c: int, like: str) -> None:
    """``x`` the contacts' status (C,): 0 open, 1 sticking, 2 sliding."""
    a = shaped(fn, name, x, (c,), like, empty_ok=True)
    if a.size and not (a.min() >= 0 and a.max() <= 2):
        fail(fn, name, "hold 0 (open), 1 (sticking) or 2 (sliding)",
             f"values in [{a.min()}, {a.max()}]")


def numbers(fn: str, **arrays) -> None:
    """Numbers or arrays of numbers (name=value; NaN allowed) that combine element by element."""
    if all(type(a) in _PLAIN for a in arrays.values()):
        return
    for k, a in arrays.items():
        asarray(fn, k, a)
    broadcast(fn, **arrays)


def broadcast(fn: str, **arrays) -> None:
    """The arrays (name=array) combine element by element (numpy broadcasting)."""
    if all(type(a) in _PLAIN for a in arrays.values()):
        return
    try:
        np.broadcast_shapes(*(np.shape(a) for a in arrays.values()))
    except ValueError:
        shapes = ", ".join(f"{k} {np.shape(a)}" for k, a in arrays.items())
        fail(fn, " and ".join(arrays), "have the same shape (or broadcast)", shapes)


def same_length(fn: str, **arrays) -> int:
    """One-dimensional arrays (name=array) of one length; returns it."""
    lengths = {k: np.shape(a) for k, a in arrays.items()}
    names = list(arrays)
    for k, s in lengths.items():
        if len(s) != 1:
            fail(fn, k, "be one-dimensional (one value per frame or sample)", f"shape {s}")
    first = lengths[names[0]][0]
    odd = [k for k in names if lengths[k][0] != first]
    if odd:
        fail(fn, odd[0], f"have the length of {names[0]} ({first})", str(lengths[odd[0]][0]))
    return first


def table(fn: str, name: str, df, columns=()) -> None:
    """``df`` a pandas DataFrame holding ``columns``."""
    import pandas as pd
    if not isinstance(df, pd.DataFrame):
        fail(fn, name, "be a pandas DataFrame", type(df).__name__, TypeError)
    missing = [c for c in columns if c not in df.columns]
    if missing:
        have = ", ".join(map(str, df.columns[:20])) + (", ..." if len(df.columns) > 20 else "")
        fail(fn, name, f"have the column(s) {', '.join(map(repr, missing))}",
             f"columns {have or '(none)'}")


def function(fn: str, name: str, x) -> None:
    """``x`` callable."""
    if not callable(x):
        fail(fn, name, "be a function", kind_of(x), TypeError)
