"""The reproduction report: each claim of the paper against our numbers, from the figures' JSON.

``tiltpile report --figures figures --out paper/REPRODUCTION.md`` (run by ``make figures``) reads
``figures/fig*.json`` (written by the notebooks through :func:`tiltpile.figures.style.save`) and
writes a Markdown table: the paper's value, ours, the preset and the number of runs it came from,
and a verdict (agrees / disagrees / inconclusive), followed by notes on every disagreement, the
headline numbers of Fig. 2 at each scale that has been run (smoke, default, paper; "not yet run"
otherwise), the preparation study, and for every claim the paper's sentence and the rule that
judges it. :func:`inputs` lists every file it reads.

Verdicts are computed, not written by hand: each :class:`Claim` has a ``judge`` that looks at the
numbers and returns a :class:`~.judging.Judgement`: the verdict, the code of its reason and the
numbers it rests on (``values``), no sentence; our value and the note (its ``ours`` and
``note``) are the Jinja2 macros of ``templates/claims.md.j2`` for that claim and reason,
rendered from the values.

One concern per module; the names of ``__all__`` import from ``tiltpile.report``:

- :mod:`.main`: the main report, ``paper/REPRODUCTION.md`` (``tiltpile report`` without
  ``--figures``): the paper's scale first with every axis beside it, rendered from data by the
  Jinja2 template ``templates/main.md.j2``;
- :mod:`.blocks`: the generated blocks of the README and the docs (``tiltpile docs``), rendered by
  the templates ``templates/readme_*.md.j2`` and ``templates/presets_*.md.j2``;

- :mod:`.judging`: what a claim, its rule and a judgement are, the four verdicts, the sentences'
  environment, and the helpers that read and print the numbers (shared by the judges, the
  sentences' filters and the tables);
- :mod:`.paper`: the paper's claims (Figs. 1-6, the avalanche angle), their judges and rules;
- :mod:`.rigidity`: the claims beyond the paper (the rigid clusters, Fig. 7), likewise;
- :mod:`.claims`: all of them in the report's order (``CLAIMS``) with their rules (``RULES``);
- :mod:`.scales`: Fig. 2's headline numbers at every scale, and where each scale's figures live;
- :mod:`.studies`: the preparation study's section and what the notes cite from the preparation
  and <z>-counting studies;
- :mod:`.definitions`: the section "What the disagreements depend on": every claim judged under
  each definition of the definitions study (``tiltpile definitions``);
- :mod:`.engines`: the section "Same piles, another model": the default piles in the second
  engine (the soft-sphere DEM), pile against pile, and which disagreements both engines share;
- :mod:`.history_rate`: the section "The history at 10x the ramp's rate": paper-fast against
  paper pile against pile, the figure numbers against what chance moves, the decision;
- :mod:`.friction`: the section "Friction": the friction study, the Mohr-Coulomb reading tested
  across frictions, and the angles beside the literature's;
- :mod:`.wall`: the wall time of the runs behind a figure document, from their committed
  records (the figures' JSON hold none);
- :mod:`.document`: loading, rendering and writing the report, and the files it reads.
"""

from __future__ import annotations

from .claims import CLAIMS, RULES
from .document import inputs, load_figures, render, root_inputs, write_report, write_studies
from .judging import AGREES, DISAGREES, INCONCLUSIVE, MISSING, Claim, Rule
from .paper import CLAIMS_123, CLAIMS_456, RULES_PAPER
from .rigidity import BEYOND, CLAIMS_RIGIDITY, RULES_RIGIDITY
from .scales import SCALES, render_scales, scale_dirs
from .studies import QUIET_WINDOW_DEG, STUDIES, load_studies, render_preparation

__all__ = ["AGREES", "BEYOND", "CLAIMS", "CLAIMS_123", "CLAIMS_456", "CLAIMS_RIGIDITY",
           "DISAGREES", "INCONCLUSIVE", "MISSING", "QUIET_WINDOW_DEG", "RULES", "RULES_PAPER",
           "RULES_RIGIDITY", "SCALES", "STUDIES", "Claim", "Rule", "inputs", "load_figures",
           "load_studies", "render", "render_preparation", "render_scales", "root_inputs", "scale_dirs",
           "write_report", "write_studies"]
