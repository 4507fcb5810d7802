"""Side studies, one module each: what a study varies (its settings, as data), the plan validated
before anything runs, its comparison with the committed setting, its JSON, chart and report
section. The command that runs a study lives in :mod:`tiltpile.cli` (one module per command); a
study module holds only its Python API.

Modules:

* ``solver``: the solver's choice (issue 72): one ensemble of the default preset per NLGS setting
  (sweep order, cap, tolerance, time step), each compared with the committed setting pile against
  pile and claim by claim (:mod:`tiltpile.figures.same_piles`, the report's judges), its cost per
  run and its health stops; the chart of cost against the numbers moved, and the report section
  "What the solver's choice changes" (``tiltpile solver-study``).
"""
