"""Figures of Henkes, Brito, Dauchot & van Saarloos, "Local Coulomb versus Global Failure Criterion
for Granular Packings" (paper/), one module per figure, used by the notebooks in ``notebooks/``.

Each figure module -- ``fig1``, ``fig2``, ``fig3``, ``fig4``, ``fig5``, ``fig6`` (the paper's)
and ``fig7`` (beyond it: the rigid clusters) -- goes with the notebook ``notebooks/figN_<name>.ipynb``, which writes ``FIGURES/figN_<name>.png``,
``.pdf`` and ``.json`` (the stem is its ``NAME``), and has

``READS``
    the table columns it reads (an :class:`tiltpile.analysis.ensemble_data.Reads`): its
    notebook loads only those, and from records only those are checked;
``compute(ens, ...) -> (numbers, data)``
    pure analysis on an :class:`~tiltpile.analysis.ensemble_data.Ensemble` (:func:`data.load`),
    its keyword parameters and their defaults the figure's own, declared here only:
    ``numbers`` is a flat-ish dict of the scalars and short lists the figure reports (written
    to its JSON, read by the report and locked by the regression tests), ``data`` whatever the
    plot needs (DataFrames, arrays);
``plot(data, numbers) -> matplotlib.figure.Figure``
    drawing only, in the shared style of :mod:`tiltpile.figures.style`.

The other modules:

``build``         one figure from any data: its parameters (the analysis' and ``compute``'s),
                  its ensemble, numbers, drawing and files; what the notebooks, ``tiltpile
                  figure`` and the studies call
``data``          what every notebook starts from: :func:`data.load` (an ensemble directory, run
                  files or their records, with the columns a figure reads), per-run quiet means
``style``         the palette, sizes, drawing helpers and :func:`style.save` (PNG, PDF, JSON)
``snapshot``      the pile pictures of Figs. 1b, 3 and 7, and the frames they show
``parameters``    the notebook parameters given to ``make`` (``NB=``), checked against the
                  figures' parameters before anything runs
``records``       what a run's record keeps (``tiltpile record``; the layout: :mod:`tiltpile.record`)
``preparation``   the preparation study: Fig. 2's numbers on ensembles of several histories
``zcount``        <z> under each counting rule (``tiltpile zcount``)
``same_piles``    the same piles under two settings, pile against pile (``tiltpile same-piles``)
``study``         a parameter study's numbers and figure (``tiltpile study``)
``definitions``   every figure number under each definition the paper leaves open
                  (``tiltpile definitions``)
``kernel``        the IPython extension of the notebooks' kernel (``make setup``): no ERROR line
                  from papermill's shutdown interrupt
"""
