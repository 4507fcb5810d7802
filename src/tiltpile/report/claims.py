"""Every claim the report judges, in the report's order, and the rule of each: the paper's
(:mod:`.paper`) and ours beyond it (:mod:`.rigidity`)."""

from __future__ import annotations

from .judging import Claim, Rule
from .paper import CLAIMS_123, CLAIMS_456, RULES_PAPER
from .rigidity import CLAIMS_RIGIDITY, RULES_RIGIDITY

CLAIMS: list[Claim] = CLAIMS_123 + CLAIMS_456 + CLAIMS_RIGIDITY
RULES: dict[str, Rule] = {**RULES_PAPER, **RULES_RIGIDITY}
