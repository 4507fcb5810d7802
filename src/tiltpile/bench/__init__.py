"""Measurements: what the simulator costs and how accurate it is. The results, dated, are in
``docs/performance-log.md`` (summarized in ``docs/performance.md``); ``make bench`` regenerates ``figures/performance/``.

Every module runs as ``python -m tiltpile.bench.<name>`` through ``main(argv)`` and measures
nothing when imported (``python -m tiltpile.bench`` lists them):

``pile``               the settled piles every measurement starts from, cached in data/bench
``timing``             ``tiltpile bench``: the cost of a step on a settled pile of n grains
``chart``              ``make bench``: the speed x accuracy chart (``spec``, ``accuracy``,
                       ``scaling``, ``plots``), written to figures/performance/
``solver_micro``       ns per contact update of each sweep order, one process
``solver_variants``    sweeps, cost and true error of NLGS variants while tilting
``flow_caps``          the iteration cap in a flowing pile, from a frame of a run
``precursor_caps``     the iteration cap between precursor events, from frames of a run
``settle``             when NLGS velocities settle (LMGC90's norms) against the motion of a long solve
``coarse``             the most a coarse correction (rigid blocks, block stresses) could remove of NLGS's error
``compare_ensembles``  onset, z and n_m of ensembles that differ in one setting
``guard``              what a cheaper setting costs against how far it moves the figure numbers
``store_filters``      size and time of the run file's checksums and of compression
``dask_overhead``      the CPU dask's housekeeping takes from an ensemble's runs
``ke_threshold``       how Fig. 2a's kinetic-energy threshold moves as runs are added or left out
``code_change``        whether an analysis edit keeps the tables' values (old commit against this one)

Measurement code sits beside the command line: it imports ``config``, ``sim``, ``store`` and
``analysis``, never ``figures`` or ``cli`` (``tests/test_layers.py``).
"""

STUDIES = ("pile", "timing", "chart", "solver_micro", "solver_variants", "flow_caps",
           "precursor_caps", "settle", "coarse", "compare_ensembles", "guard", "store_filters",
           "dask_overhead", "ke_threshold", "code_change")
