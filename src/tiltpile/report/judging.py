"""What a claim is and how its judge writes its verdict: :class:`Claim`, :class:`Rule`, the four
verdicts, and the helpers the judges and the report's tables share to read and print the figures'
numbers: :func:`num` (a number of the JSON, NaN where missing), :func:`show` (printed, "n/a" where
missing), :func:`show_ci` and :func:`show_interval` (with a bootstrap interval),
:func:`overlaps`, :func:`wrong_side` (a cutoff against two fitted populations) and
:func:`verdict_of` (the verdict of a judged test).

Each judge tests what the paper's sentence says, with a stated tolerance; ensemble means carry a
95% bootstrap interval over runs (stats.bootstrap_ci), and a verdict that depends on a mean uses
the interval, not the point. The rule of each claim is its :class:`Rule`, printed in the report's
"How each claim is tested" section.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

AGREES, DISAGREES, INCONCLUSIVE, MISSING = "agrees", "disagrees", "inconclusive", "not measured"


@dataclass(frozen=True)
class Claim:
    """One claim, declared once: its judge and its rule read the same numbers (the paper's from
    :mod:`tiltpile.paper_values`, a tolerance of ours beside the judge), the rule's text formatted
    from them."""
    key: str
    text: str              # the paper's claim, in our words
    paper: str             # the paper's value
    figure: str            # figure JSON stem the numbers come from
    judge: Callable[[dict], tuple[str, str, str]]   # numbers -> (ours, verdict, note)
    rule: Rule | None = None   # what the paper says and what the judge tests


def approx(x: float, digits: int) -> str:
    """``x`` to ``digits`` significant digits, but never in exponent notation from 1 on: the
    core-hours of an ensemble (105 to two digits is '105', where '.2g' gives '1e+02')."""
    s = f"{x:.{digits}g}"
    return f"{x:.0f}" if "e+" in s else s


def show(x, fmt: str = ".3g") -> str:
    """``x`` formatted with ``fmt``; "n/a" for None, NaN or an infinity."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return format(x, fmt)


@dataclass(frozen=True)
class Rule:
    sentence: str          # what the paper says (quoted or closely paraphrased)
    test: str              # what we compute and when it agrees


def num(x) -> float:
    """``x`` as a float, NaN for None (a number the JSON holds as null)."""
    return float("nan") if x is None else float(x)


def verdict_of(ok, measurable: bool = True) -> str:
    """AGREES or DISAGREES as ``ok``; INCONCLUSIVE when the number is not ``measurable``."""
    if not measurable:
        return INCONCLUSIVE
    return AGREES if ok else DISAGREES


def show_ci(n: dict, key: str, fmt: str = ".2f", est: str | None = None) -> str:
    """'x [lo, hi]' of numbers key, key_ci_low, key_ci_high ('x' alone without an interval)."""
    x = num(n.get(est or key))
    lo, hi = num(n.get(f"{key}_ci_low")), num(n.get(f"{key}_ci_high"))
    if math.isfinite(lo) and math.isfinite(hi):
        return f"{show(x, fmt)} [{show(lo, fmt)}, {show(hi, fmt)}]"
    return show(x, fmt)


def overlaps(lo: float, hi: float, a: float, b: float) -> bool:
    """Whether the interval [lo, hi] (finite) meets [a, b]."""
    return math.isfinite(lo) and math.isfinite(hi) and lo <= b and hi >= a


def show_interval(d: dict, fmt: str = ".2f") -> str:
    """'x [lo, hi]' of a {"estimate", "low", "high"} interval."""
    d = d or {}
    return (f"{show(num(d.get('estimate')), fmt)} [{show(num(d.get('low')), fmt)}, "
            f"{show(num(d.get('high')), fmt)}]")


# A cutoff separates two populations when at most this share of either lies on its wrong side:
# the share of a Gaussian beyond one standard deviation from its mean (15.9%).
SEPARATION = 0.5 * math.erfc(1.0 / math.sqrt(2.0))


def wrong_side(b: dict, cutoff: float) -> tuple[float, float]:
    """(share of the lower population above ``cutoff``, share of the upper one below it) of the
    two Gaussians fig2 fits to log10 of the lost fraction (its ``lost_bimodality`` means, sds);
    NaNs where they are missing."""
    means, sds = b.get("means") or [], b.get("sds") or []
    vals = [num(v) for v in (*means, *sds)]
    if len(means) != 2 or len(sds) != 2 or not all(math.isfinite(v) for v in vals) or not cutoff > 0:
        return float("nan"), float("nan")
    (m1, m2), (s1, s2), c = vals[:2], vals[2:], math.log10(cutoff)
    if s1 <= 0 or s2 <= 0:
        return float("nan"), float("nan")
    return (0.5 * math.erfc((c - m1) / (s1 * math.sqrt(2.0))),
            0.5 * math.erfc((m2 - c) / (s2 * math.sqrt(2.0))))
