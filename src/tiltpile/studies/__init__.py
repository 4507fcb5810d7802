"""Side studies, one module each: what a study varies (its settings, as data), the plan validated
before anything runs, its comparison with the committed setting, its JSON, chart and report
section. The command that runs a study lives in :mod:`tiltpile.cli` (one module per command); a
study module holds only its Python API.

Modules:

* ``settings``: what the studies share: the plan (settings as data, each configuration validated
  before anything runs), the runs as the manifest recorded them (health stops as failed
  settings), the records and their cost, the same-piles comparisons kept with the digest of
  their inputs, the claims' verdicts and flips, a setting's entry of a study's JSON, the stages a
  study's command runs (ensembles, records) and the words of a report section.
* ``solver``: the solver's choice (issue 72): one ensemble of the default preset per NLGS setting
  (sweep order, cap, tolerance, time step), each compared with the committed setting pile against
  pile and claim by claim (:mod:`tiltpile.figures.same_piles`, the report's judges), its cost per
  run and its health stops; the chart of cost against the numbers moved, and the report section
  "What the solver's choice changes" (``tiltpile solver-study``).
* ``stiffness``: the second engine in its rigid limit (issue 73): one DEM ensemble of
  default-dem's piles per contact stiffness (k_n, 4 k_n at dt / 2, 16 k_n at dt / 4), each
  compared with k_n and with Contact Dynamics on the same piles; every number against 1 / k_n,
  extrapolated to the rigid limit where the trend allows it; every claim's verdict across the
  stiffnesses and in both engines; the cost per run and at the paper's scale; the report section
  "The second engine in its rigid limit" (``tiltpile stiffness-study``).
"""
