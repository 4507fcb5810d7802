"""Measurements: what the simulator costs and how accurate it is. The results, dated, are in
``notes/performance-log.md`` (summarized in ``docs/performance.md``); ``make bench`` regenerates ``figures/performance/``.

This package sits beside ``tiltpile``, in the repository, and is not installed with it: it
imports the installed ``tiltpile`` and runs from the repository's root. Every module runs as
``python -m benchmarks.<name>`` through ``main(argv)`` and measures nothing when imported
(``python -m benchmarks`` lists them, from the package itself):

``pile``               the settled piles every measurement starts from, cached in data/bench
``timing``             the cost of a step on a settled pile of n grains
``chart``              ``make bench``: the speed x accuracy chart (``spec``, ``accuracy``,
                       ``scaling``, ``plots``), written to figures/performance/
``solver_micro``       ns per contact update of each sweep order, one process
``solver_variants``    sweeps, cost and true error of NLGS variants while tilting
``solver_frames``      z, n_m and sliding contacts of one step re-solved at each sweep cap, order
                       and start (frames of a run, or bench piles): ``docs/solver-frames.md``
``compare_ensembles``  onset, z and n_m of ensembles that differ in one setting
``guard``              what a cheaper setting costs against how far it moves the figure numbers
``kill_resume``        how often a SIGKILL at a random moment leaves a run resumable (the frame log)
``code_change``        whether an analysis edit keeps the tables' values (old commit against this
                       one), and the ``analysis.legacy_codes.SUPERSEDED`` entries that carry the
                       records over it
``machine_code``       the simulator kernels' machine code, normalized: two versions of ``sim/``
                       compared without a quiet core (identical code, identical speed)

These are the tools in use. The finished studies (``coarse``, ``settle``, ``flow_caps``,
``precursor_caps``, ``store_filters``, ``dask_overhead``, ``ke_threshold``) left the package
(then ``tiltpile.bench``) after f4398d3, which holds them with their tests; docs/performance.md ("How to measure") says
how to run one there, and each entry of notes/performance-log.md gives its command.
(``tests/bench/test_listing.py`` keeps this table equal to the package's modules.)

Measurement code imports ``tiltpile``'s ``config``, ``sim``, ``store`` and ``analysis``, never
its ``figures`` or ``cli``; nothing in ``tiltpile`` imports it (``tests/test_architecture.py``).
"""


def tools() -> list[str]:
    """The modules and subpackages of ``benchmarks`` that run as ``python -m``, by name (what
    ``python -m benchmarks`` lists): read from the package's directory, so none is left out."""
    import pkgutil

    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
