"""What a claim is and what its judge returns: :class:`Claim`, :class:`Rule`, the four verdicts,
the :class:`Judgement` (a verdict, the code of its reason and the numbers it rests on, its
sentences rendered from ``templates/claims.md.j2``), and the helpers the judges and the report's
tables share to read and print the figures' numbers: :func:`num` (a number of the JSON, NaN where
missing), :func:`show` (printed, "n/a" where missing), :func:`show_ci` and :func:`show_interval`
(with a bootstrap interval), :func:`interval_of` and :func:`estimate_of` (the same three numbers
as a list, for a judgement's values), :func:`overlaps`, :func:`wrong_side` (a cutoff against two
fitted populations) and :func:`verdict_of` (the verdict of a judged test).

Each judge tests what the paper's sentence says, with a stated tolerance; ensemble means carry a
95% bootstrap interval over runs (stats.bootstrap_ci), and a verdict that depends on a mean uses
the interval, not the point. The rule of each claim is its :class:`Rule`, printed in the report's
"How each claim is tested" section.

A judge writes no sentence: it returns a :class:`Judgement`, and the sentences that quote its
numbers are the Jinja2 macros of ``templates/claims.md.j2``, ``<key>__ours`` (our value) and
``<key>__<reason>`` (the note of that reason; none: no note), the numbers formatted by the
filters ``show``, ``ci``, ``interval``, ``fmt`` and ``sci``. A claim without an ``__ours`` macro
prints its values as ``name = value``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Callable

AGREES, DISAGREES, INCONCLUSIVE, MISSING = "agrees", "disagrees", "inconclusive", "not measured"
#: the template of the judgements' sentences (module docstring)
SENTENCES = "claims.md.j2"
#: the reason of a claim whose figure is missing (its sentences are the template's ``no_figure__*``)
NO_FIGURE = "no_figure"


@dataclass(frozen=True)
class Judgement:
    """What a judge finds on a figure's numbers: the ``verdict`` (one of the four), the
    ``reason`` (a short code naming why, one per sentence the note can say), and the ``values``
    its sentences quote (plain numbers, lists and strings; NaN where a number is missing), all
    keyed by the ``claim`` it judges. :attr:`ours` and :attr:`note` render its sentences from
    ``templates/claims.md.j2`` (module docstring)."""
    claim: str                 # the claim's key: its macros are <claim>__ours, <claim>__<reason>
    verdict: str
    reason: str
    values: dict = field(default_factory=dict)

    def _macros(self) -> tuple[str, str]:
        if self.reason == NO_FIGURE:
            return f"{NO_FIGURE}__ours", f"{NO_FIGURE}__note"
        return f"{self.claim}__ours", f"{self.claim}__{self.reason}"

    @property
    def ours(self) -> str:
        """Our value as the report's table prints it."""
        said = say(self._macros()[0], self.values)
        return say("default__ours", list(self.values.items()), plain=True) if said is None else said

    @property
    def note(self) -> str:
        """Why the claim does not agree, or ""."""
        said = say(self._macros()[1], self.values)
        return "" if said is None else said


def missing(claim: Claim) -> Judgement:
    """The judgement of a claim whose figure the directory does not hold."""
    return Judgement(claim.key, MISSING, NO_FIGURE, {"figure": claim.figure})


def judge_document(claim: Claim, doc: dict) -> Judgement:
    """``claim``'s judgement on a figure document: its numbers, with the piles' history and the
    number of grains beside them (a note may depend on them)."""
    return claim.judge({**doc.get("numbers", {}), "history": doc.get("history"),
                        "n_grains": doc.get("n_grains")})


def say(macro: str, values, plain: bool = False) -> str | None:
    """The sentence of ``macro`` of ``templates/claims.md.j2`` on ``values`` (a dict, given to
    the macro as an object whose attributes are its keys; ``plain``: as it is), its lines joined
    by single spaces (the template wraps its sentences); None where there is no such macro."""
    m = getattr(_sentences(), macro, None)
    if m is None:
        return None
    text = str(m(values if plain else SimpleNamespace(**values)))
    return " ".join(line.strip() for line in text.splitlines() if line.strip())


@functools.lru_cache(maxsize=1)
def _sentences():
    """The template's module (its exported macros), once."""
    return environment().get_template(SENTENCES).module


def environment():
    """The Jinja2 environment of the sentences: the report's templates, StrictUndefined (a
    value a sentence names and the judge did not give is an error), and the filters that print
    numbers as the judges used to."""
    import jinja2

    def strict(f):
        """``f`` failing on an undefined value as printing it would (a filter is handed it)."""
        def g(x, *args):
            if isinstance(x, jinja2.Undefined):
                x._fail_with_undefined_error()
            return f(x, *args)
        return g

    env = jinja2.Environment(loader=jinja2.PackageLoader("tiltpile.report", "templates"),
                             undefined=jinja2.StrictUndefined, autoescape=False)
    env.filters.update(show=strict(show), ci=strict(_show_triple),
                       interval=strict(_show_interval_triple), fmt=strict(format), sci=strict(sci))
    env.tests["finite"] = strict(lambda x: isinstance(x, (int, float)) and math.isfinite(x))
    return env


@dataclass(frozen=True)
class Claim:
    """One claim, declared once: its judge and its rule read the same numbers (the paper's from
    :mod:`tiltpile.paper_values`, a tolerance of ours beside the judge), the rule's text formatted
    from them."""
    key: str
    text: str              # the paper's claim, in our words
    paper: str             # the paper's value
    figure: str            # figure JSON stem the numbers come from
    judge: Callable[[dict], Judgement]   # numbers -> Judgement (verdict, reason, values)
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
    return _show_triple(interval_of(n, key, est), fmt)


def interval_of(n: dict, key: str, est: str | None = None) -> list[float]:
    """[x, lo, hi] of numbers key (or ``est``), key_ci_low, key_ci_high (NaN where missing): what
    :func:`show_ci` prints, as a judgement's value (the ``ci`` filter prints it)."""
    return [num(n.get(est or key)), num(n.get(f"{key}_ci_low")), num(n.get(f"{key}_ci_high"))]


def estimate_of(d: dict | None) -> list[float]:
    """[estimate, low, high] of a {"estimate", "low", "high"} interval (NaN where missing): what
    :func:`show_interval` prints, as a judgement's value (the ``interval`` filter prints it)."""
    d = d or {}
    return [num(d.get("estimate")), num(d.get("low")), num(d.get("high"))]


def _show_triple(t, fmt: str = ".2f") -> str:
    """[x, lo, hi] as :func:`show_ci` prints it: 'x [lo, hi]', 'x' alone without an interval."""
    x, lo, hi = t
    if math.isfinite(lo) and math.isfinite(hi):
        return f"{show(x, fmt)} [{show(lo, fmt)}, {show(hi, fmt)}]"
    return show(x, fmt)


def _show_interval_triple(t, fmt: str = ".2f") -> str:
    """[estimate, low, high] as :func:`show_interval` prints it: 'x [lo, hi]'."""
    x, lo, hi = t
    return f"{show(x, fmt)} [{show(lo, fmt)}, {show(hi, fmt)}]"


def sci(x: float) -> str:
    """1e-3 as '1e-3' (one significant digit, the exponent without padding)."""
    mant, exp = f"{x:.0e}".split("e")
    return f"{mant}e{int(exp)}"


def overlaps(lo: float, hi: float, a: float, b: float) -> bool:
    """Whether the interval [lo, hi] (finite) meets [a, b]."""
    return math.isfinite(lo) and math.isfinite(hi) and lo <= b and hi >= a


def show_interval(d: dict, fmt: str = ".2f") -> str:
    """'x [lo, hi]' of a {"estimate", "low", "high"} interval."""
    return _show_interval_triple(estimate_of(d), fmt)


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
