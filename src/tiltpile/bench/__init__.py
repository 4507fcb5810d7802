"""Measurements: what the simulator costs and how accurate it is. The results, dated, are in
``docs/performance-log.md`` (summarized in ``docs/performance.md``); ``make bench`` regenerates ``figures/performance/``.

Every module runs as ``python -m tiltpile.bench.<name>`` through ``main(argv)`` and measures
nothing when imported (``python -m tiltpile.bench`` lists them). The live tools:

``pile``               the settled piles every measurement starts from, cached in data/bench
``timing``             ``tiltpile bench``: the cost of a step on a settled pile of n grains
``chart``              ``make bench``: the speed x accuracy chart (``spec``, ``accuracy``,
                       ``scaling``, ``plots``), written to figures/performance/
``solver_micro``       ns per contact update of each sweep order, one process
``solver_variants``    sweeps, cost and true error of NLGS variants while tilting
``compare_ensembles``  onset, z and n_m of ensembles that differ in one setting
``guard``              what a cheaper setting costs against how far it moves the figure numbers
``kill_resume``        how often a SIGKILL at a random moment leaves a run resumable
``code_change``        whether an analysis edit keeps the tables' values (old commit against this
                       one), and the ``analysis.legacy_codes.SUPERSEDED`` entries that carry the
                       records over it

Any other module here is a finished study: no tool and nothing outside the studies imports it,
and docs/performance-log.md records its measurements under its command
(``tiltpile.bench.<name>``); tests/test_architecture.py checks both.

Measurement code sits beside the command line: it imports ``config``, ``sim``, ``store`` and
``analysis``, never ``figures`` or ``cli`` (``tests/test_layers.py``).
"""

STUDIES = ("pile", "timing", "chart", "solver_micro", "solver_variants", "flow_caps",
           "precursor_caps", "settle", "coarse", "compare_ensembles", "guard", "store_filters",
           "dask_overhead", "ke_threshold", "code_change")
