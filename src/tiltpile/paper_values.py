"""The paper's values: every number of the paper (and of the paper of its simulations) that the
code judges against or takes over, once, with where it is given and, for a number the report
judges, the band a measurement of ours is judged in.

The paper is Henkes, Brito, Dauchot & van Saarloos (2010), paper/henkes2010_*.tex; "Deboeuf et
al." is the paper of the simulations it analysed, S. Deboeuf, O. Dauchot, L. Staron, A. Mangeney
and J.-P. Vilotte, Phys. Rev. E 72, 051305 (2005) (the paper's reference Stephanie_PRE05). Why
each band is as wide as it is: the rule of its claim (``tiltpile.report.paper``, printed in the
report's "How each claim is tested"), whose sentence is formatted from the same band.

Who reads them: the report's judges and rules (``report.paper``), the preparation study's
section (``report.studies``) and its count of runs quiet past Fig. 5's window
(``figures.preparation``), Fig. 2's avalanche threshold and Fig. 5's windows and guide slope
(``figures.fig2``, ``figures.fig5``), the slide of ``tiltpile repose`` (``repose``,
``cli.repose``) and the <z> that the counting-rule study looks for (``analysis.zcount``). What
cannot import them states them again, and ``tests/test_paper_values.py`` equates the two: the
paper preset's ``protocol.end_ke`` (src/tiltpile/presets/paper.toml) and the notebooks'
parameters (Fig. 2's ``avalanche_ke``, Fig. 5's ``windows`` and ``delta_guide``).

This module imports nothing of tiltpile, so that every layer may read it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Value:
    """A number the paper gives, where it gives it, and the band a measurement is judged in:
    ``value`` +- ``tol``, or ``band`` where the band is not symmetric in that way (neither: the
    number is not judged as a band)."""

    value: float
    source: str                                   # where the paper (or the paper it cites) says it
    tol: float | None = None                      # judged within value +- tol ...
    band: tuple[float, float] | None = None       # ... or within this closed interval

    @property
    def lo(self) -> float:
        return self.band[0] if self.band is not None else self.value - self.tol

    @property
    def hi(self) -> float:
        return self.band[1] if self.band is not None else self.value + self.tol


QUIET_DEG = Value(
    14.4, "Fig. 5's caption: its farthest window of quiet clusters is at theta - theta_m = "
          "-14.4 deg, so some of the paper's piles had no 2% onset before 14.4 deg")

# Fig. 5's windows of theta - theta_m (deg), its caption's order: the farthest is QUIET_DEG
FIG5_WINDOWS_DEG = (-QUIET_DEG.value, -4.6, -0.75, -0.25)

AVALANCHE_DEG = Value(
    21.0, "Deboeuf et al. (2005): the avalanche angle theta_a ~ 21 deg of these piles (4000 "
          "grains), the large surface slide; quoted without error", tol=2.0)

REPOSE_DEG = Value(
    15.0, "Deboeuf et al. (2005): the repose angle theta_r ~ 15 deg of these piles, where the "
          "flow stops when the pile is tilted back")

Z_MEAN = Value(
    3.5, "text before Fig. 4: \"The average number of contacts for the whole pile is <z> ~ "
         "3.5\"", band=(3.45, 3.55))

ONSET_SHIFT_FRAMES = Value(
    2, "text on Fig. 2b: varying the cutoff between 1% and 4% \"typically changes the location "
       "of the onset of the avalanche by 1-2 frames\"")

ORIENTATION_DEG = Value(
    60.0, "text on Fig. 3 (top): the clusters' \"preferential direction of alignment makes an "
          "angle of roughly 60 deg with respect to gravity\"", tol=10.0)

ENHANCEMENT = Value(
    0.40, "text on Fig. 3 (bottom right): \"just after the cluster size peaks, the failure rate "
          "is enhanced by about 40%\"", band=(0.2, 0.6))

DELTA = Value(
    2.5, "text on Fig. 5 (Eq. 3): \"We have estimated delta = 2.5 +- 0.25 from the "
         "distribution just above onset\"; Fig. 5's dashed guide has this slope", tol=0.25)

SLIDE_KE = Value(
    1e-3, "ours, standing for Deboeuf et al.'s large slide: the kinetic energy per mobile grain "
          "[m g d] of a large slide of our piles (1e-3 to 1e-2; precursors 1e-5 to 5e-4, quiet "
          "frames below 1e-6: docs/method.md), the threshold of the avalanche angle (Fig. 2), "
          "of `tiltpile repose`'s slide and of the paper preset's protocol.end_ke")

# every value above, by name (the tests and the map read them from here)
VALUES: dict[str, Value] = {k: v for k, v in globals().items() if isinstance(v, Value)}
