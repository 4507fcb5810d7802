"""One figure from any data: its parameters, its ensemble, its numbers, its drawing and files.

A figure's parameters are declared once: the analysis parameters of the tables
(:data:`tiltpile.analysis.DEFAULT_PARAMS`; those of the per-run table only for a figure that
reads it, ``READS_RUN_TABLE``) and the keyword parameters of its module's ``compute`` (their
defaults are the figure's; the paper's numbers come from :mod:`tiltpile.paper_values`). Everything that makes a figure goes through here: its notebook
(``notebooks/figN_<name>.ipynb``, whose parameters cell holds only the data, the preset, the
output directory and ``overrides``), ``tiltpile figure NAME DATA --set key=value``, and the
studies that compute figure numbers on other ensembles (same piles, definitions, settings),
which call :func:`document` directly.

A parameter name given twice (an analysis parameter of the per-run table is also a keyword of
Fig. 2's ``compute``) is the analysis', as the notebooks have always passed it.
"""

from __future__ import annotations

import inspect
import json
from dataclasses import replace
from pathlib import Path

from tiltpile.analysis import DEFAULT_PARAMS
from tiltpile.analysis.observables import RUN_TABLE_PARAMS

from . import data as _data
from . import fig1, fig2, fig3, fig4, fig5, fig6, fig7, style

#: the figures, by short name, in the paper's order (fig7 goes beyond the paper)
MODULES = {"fig1": fig1, "fig2": fig2, "fig3": fig3, "fig4": fig4, "fig5": fig5, "fig6": fig6,
           "fig7": fig7}
#: the figures' stems (their notebooks, their files), by short name
STEMS = {name: mod.NAME for name, mod in MODULES.items()}


def figure_name(name: str) -> str:
    """The short name ("fig5") of ``name``, a short name or a stem ("fig5_cluster_sizes");
    ValueError naming the figures for another."""
    if name in MODULES:
        return name
    for short, stem in STEMS.items():
        if name == stem:
            return short
    raise ValueError(f"no figure {name!r}; the figures are {', '.join(MODULES)} "
                     f"({', '.join(STEMS.values())})")


def figure_parameters(name: str) -> dict:
    """{parameter: default} of the figure's own parameters (its ``compute``'s keywords), those
    the analysis also has left out."""
    sig = inspect.signature(MODULES[figure_name(name)].compute)
    return {k: p.default for k, p in list(sig.parameters.items())[1:]
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and k not in DEFAULT_PARAMS}


def analysis_parameters(name: str) -> dict:
    """{parameter: default} of the analysis parameters the figure takes: the tables', and the
    per-run table's where it reads that table (``READS_RUN_TABLE``)."""
    runs = getattr(MODULES[figure_name(name)], "READS_RUN_TABLE", False)
    return {k: v for k, v in DEFAULT_PARAMS.items() if runs or k not in RUN_TABLE_PARAMS}


def parameters(name: str) -> dict:
    """{parameter: default} of every parameter of the figure: the analysis' then its own."""
    return {**analysis_parameters(name), **figure_parameters(name)}


def given(name: str, overrides: dict | None = None, namespace: dict | None = None) -> dict:
    """Every parameter of the figure, at its default unless ``overrides`` gives it or, where a
    notebook runs, ``namespace`` (its globals: what ``papermill -p NAME VALUE`` injected) holds a
    variable of its name. ValueError (one line) for an override that is not a parameter or an
    analysis parameter out of its range, TypeError for one of another type."""
    name = figure_name(name)
    known = parameters(name)
    overrides = dict(overrides or {})
    unknown = sorted(set(overrides) - set(known))
    if unknown:
        raise ValueError(f"{', '.join(unknown)}: not a parameter of {name} (its parameters: "
                         f"{', '.join(known)}; `tiltpile figure {name} --list`)")
    injected = {k: v for k, v in (namespace or {}).items() if k in known and k not in overrides}
    out = {**known, **injected, **overrides}
    from tiltpile.analysis.tables import _params
    _params({k: out[k] for k in DEFAULT_PARAMS if k in out})   # one line for a value out of range
    return out


def _split(name: str, params: dict) -> tuple[dict, dict]:
    own = figure_parameters(name)
    return ({k: params[k] for k in analysis_parameters(name) if k in params},
            {k: params[k] for k in own if k in params})


def load(name: str, data_dir, preset: str | None = None, **params):
    """The ensemble of ``data_dir`` (run files or records) with the columns the figure reads,
    at the analysis parameters of ``params`` (:func:`tiltpile.figures.data.load`)."""
    name = figure_name(name)
    analysis, _ = _split(name, given(name, params))
    return _data.load(data_dir, preset, MODULES[name].READS, **analysis)


def compute(name: str, ens, **params) -> tuple[dict, dict]:
    """(numbers, plot data) of the figure on ``ens`` at the figure's parameters of ``params``."""
    name = figure_name(name)
    _, own = _split(name, given(name, params))
    return MODULES[name].compute(ens, **own)


def plot(name: str, d: dict, numbers: dict):
    """The figure drawn from :func:`compute`'s plot data and numbers."""
    return MODULES[figure_name(name)].plot(d, numbers)


def save(name: str, fig, numbers: dict, figures_dir, ens) -> dict[str, Path]:
    """Write FIGURES_DIR/<stem>.pdf, .png and .json (:func:`tiltpile.figures.style.save`)."""
    return style.save(fig, STEMS[figure_name(name)], numbers, figures_dir, ens.meta)


def build(name: str, data_dir, preset: str | None = None, figures_dir=None,
          **overrides) -> dict:
    """The figure's numbers on the data of ``data_dir`` at its defaults with ``overrides``;
    drawn and written to ``figures_dir`` unless it is None."""
    name = figure_name(name)
    params = given(name, overrides)
    ens = load(name, data_dir, preset, **params)
    numbers, d = compute(name, ens, **params)
    if figures_dir is not None:
        import matplotlib.pyplot as plt
        fig = plot(name, d, numbers)
        save(name, fig, numbers, figures_dir, ens)
        plt.close(fig)
    return numbers


def document(ens, name: str, overrides: dict | None = None) -> dict:
    """The figure's JSON document on the loaded ensemble ``ens`` (what its JSON would hold:
    ``figure``, the ensemble's description, ``numbers``; NaN as None), without drawing: its
    own parameters at their defaults with ``overrides`` (the analysis ones among them must be
    those ``ens`` was loaded with: ValueError otherwise, its tables would be other ones; an
    override the figure does not have is ignored, as one study's overrides serve every figure).
    The columns the figure reads must be in ``ens``'s tables (KeyError otherwise)."""
    name = figure_name(name)
    known = parameters(name)
    params = given(name, {k: v for k, v in (overrides or {}).items() if k in known})
    analysis, own = _split(name, params)
    held = _data.analysis_params(ens)
    diff = sorted(k for k, v in analysis.items()
                  if json.dumps(v, default=str) != json.dumps(held.get(k), default=str))
    if diff:
        raise ValueError(f"{name} asks for analysis parameters {diff} other than the ensemble's "
                         "tables were computed with")
    reads = MODULES[name].READS
    for table, cols in (("frames", reads.frames), ("clusters", reads.clusters)):
        missing = sorted(set(cols) - set(getattr(ens, table).columns))
        if missing:
            raise KeyError(f"{reads.reader} reads {table} columns {missing}, which the "
                           "ensemble's tables lack")
    # described as the figure's own load would describe it (figures.data.load)
    e = replace(ens, meta=dict(ens.meta, analysis=_data.recorded_params(analysis)))
    numbers, _ = MODULES[name].compute(e, **own)
    return json.loads(json.dumps(style.document(STEMS[name], numbers, e.meta)))


def describe(name: str) -> str:
    """The figure's parameters, one per line with its default (``tiltpile figure NAME
    --list``)."""
    name = figure_name(name)
    own = figure_parameters(name)
    w = max(map(len, parameters(name)))
    lines = [f"{name} ({STEMS[name]}): its own parameters"]
    lines += [f"  {k.ljust(w)}  {v!r}" for k, v in own.items()]
    lines += ["the analysis parameters (tiltpile.analysis.DEFAULT_PARAMS; docs/method.md)"]
    lines += [f"  {k.ljust(w)}  {v!r}" for k, v in analysis_parameters(name).items()]
    return "\n".join(lines)
