"""Figures of Henkes, Brito, Dauchot & van Saarloos, "Local Coulomb versus Global Failure Criterion
for Granular Packings" (paper/), one module per figure, used by the notebooks in ``notebooks/``.

Each ``figN`` module has

``compute(frames, clusters, ...) -> (numbers, data)``
    pure analysis on the ensemble tables of :func:`tiltpile.analysis.load_observables`:
    ``numbers`` is a flat-ish dict of the scalars and short lists the figure reports (written to
    ``figures/figN_<name>.json`` and locked by the regression tests), ``data`` whatever the plot
    needs (DataFrames, arrays);
``plot(data, numbers) -> matplotlib.figure.Figure``
    drawing only, in the shared style of :mod:`tiltpile.figures.style`.

``style`` holds the palette, sizes, the pile snapshot and :func:`style.save`;
``data`` loads an ensemble directory with its manifest (:func:`data.load_ensemble`).
"""
