"""Notebook parameters given to ``make`` (``NB="-p name value ..."``): checked against the notebooks
a build executes, and each notebook's share written for papermill.

papermill passes a parameter that a notebook does not declare with a warning only, so a typo
(``-p epss 0.01``), or a parameter that none of the executed notebooks reads, would rebuild the
default numbers under a new name. ``make`` therefore runs, before anything else::

    python -m tiltpile.figures.parameters check NOTEBOOK ... -- NB

which reads NB as papermill reads its command line (``-p NAME VALUE``, ``-r NAME VALUE``,
``-y YAML``, ``-f FILE``, ``-b BASE64``; nothing else) and stops with one line, exit status 2,
naming every parameter that none of the NOTEBOOKs declares or that make sets itself
(``MAKE_SETS``); and, for each notebook it executes::

    python -m tiltpile.figures.parameters select NOTEBOOK [--note TEXT] -- NB

which prints the parameters NOTEBOOK declares, as the YAML file papermill reads with ``-f``
(``--note``: a first comment line, e.g. the data directory, so that the file changes whenever
anything make passes to the notebook does; make rebuilds a figure when its file changes).

A figure's notebook takes its figure's parameters (:func:`tiltpile.figures.build.parameters`:
the analysis parameters and its module's ``compute`` keywords), given to it as one ``overrides``
mapping, so that its parameters cell holds no copy of a default; another notebook's parameters
are the names of its ``parameters`` cell (``papermill.inspect_notebook``).
"""

from __future__ import annotations

import sys
from pathlib import Path

# set by the Makefile from DATA, PRESET, FIGURES (figures) and PREP_* (the preparation study)
MAKE_SETS = ("data_dir", "preset", "figures_dir", "data_dirs", "labels")

_PAIRS = {"-p": "p", "--parameters": "p", "-r": "r", "--parameters_raw": "r"}
_SINGLE = {"-y": "y", "--parameters_yaml": "y", "-f": "f", "--parameters_file": "f",
           "-b": "b", "--parameters_base64": "b"}


class ParameterError(ValueError):
    """NB names a parameter no notebook of the build takes, or is not papermill's syntax."""


def parse(args) -> dict:
    """The parameters papermill's command line ``args`` gives, as papermill merges them: base64,
    files, YAML, then ``-p`` (typed as papermill types them), then ``-r`` (raw strings)."""
    import base64

    import yaml
    from papermill.cli import _resolve_type
    from papermill.iorw import NoDatesSafeLoader, read_yaml_file

    given = {"p": [], "r": [], "y": [], "f": [], "b": []}
    args = list(args)
    i = 0
    while i < len(args):
        opt = args[i]
        kind = _PAIRS.get(opt) or _SINGLE.get(opt)
        n = 2 if opt in _PAIRS else 1
        if kind is None:
            raise ParameterError(f"NB takes papermill parameters only (-p NAME VALUE, -r NAME VALUE, "
                                 f"-y YAML, -f FILE, -b BASE64), got {opt!r}")
        if len(args) - (i + 1) < n:
            raise ParameterError(f"NB: {opt} needs {'NAME VALUE' if n == 2 else 'a value'}")
        given[kind].append(tuple(args[i + 1:i + 1 + n]))
        i += 1 + n
    out: dict = {}
    for (b,) in given["b"]:
        out.update(yaml.load(base64.b64decode(b), Loader=NoDatesSafeLoader) or {})
    for (f,) in given["f"]:
        out.update(read_yaml_file(f) or {})
    for (y,) in given["y"]:
        out.update(yaml.load(y, Loader=NoDatesSafeLoader) or {})
    for name, value in given["p"]:
        out[name] = _resolve_type(value)
    for name, value in given["r"]:
        out[name] = value
    return out


def _figure(notebook) -> str | None:
    """The figure whose notebook ``notebook`` is (its short name), or None."""
    from tiltpile.figures.build import STEMS

    return next((short for short, stem in STEMS.items() if Path(notebook).stem == stem), None)


def declared(notebook) -> list[str]:
    """The parameters ``notebook`` takes, in order: a figure's (module docstring), or the names
    of its parameters cell."""
    import papermill

    cell = [n for n in papermill.inspect_notebook(str(notebook)) if n != "overrides"]
    fig = _figure(notebook)
    if fig is None:
        return cell
    from tiltpile.figures.build import parameters

    return cell + [n for n in parameters(fig) if n not in cell]


def check(notebooks, params: dict) -> None:
    """ParameterError (one line) naming every parameter of ``params`` that make sets itself or
    that none of ``notebooks`` declares."""
    notebooks = [Path(n) for n in notebooks]
    names = {n: declared(n) for n in notebooks}
    known = {p for ps in names.values() for p in ps}
    ours = sorted(set(params) & set(MAKE_SETS))
    if ours:
        raise ParameterError(f"NB: {', '.join(ours)} {'is' if len(ours) == 1 else 'are'} set by "
                             "make (DATA, PRESET, FIGURES, PREP_DIRS, PREP_LABELS, PREP_FIGURES), "
                             "not by NB")
    unused = [p for p in params if p not in known]
    if unused:
        which = ", ".join(n.stem for n in notebooks) or "none"
        takes = ", ".join(sorted(known - set(MAKE_SETS))) or "none"
        raise ParameterError(f"NB: {', '.join(unused)}: not a parameter of the notebooks this build "
                             f"runs ({which}), so it would change nothing; they take: {takes}")


def select(notebook, params: dict) -> dict:
    """What papermill gives ``notebook`` of ``params``: those it declares, as ``overrides`` for a
    figure's notebook."""
    mine = set(declared(notebook))
    chosen = {k: v for k, v in params.items() if k in mine}
    if _figure(notebook) is None:
        return chosen
    return {"overrides": {k: v for k, v in chosen.items() if k not in MAKE_SETS}}


def to_yaml(params: dict, note: str | None = None) -> str:
    """``params`` as the YAML papermill reads (``-f``), after a comment line ``note``."""
    import yaml

    head = f"# {' '.join(note.split())}\n" if note else ""
    return head + yaml.safe_dump(params, default_flow_style=False, sort_keys=False)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    prog = "python -m tiltpile.figures.parameters"
    usage = (f"usage: {prog} check NOTEBOOK ... -- NB  |  {prog} select NOTEBOOK [--note TEXT] -- NB")
    if "--" in argv:
        k = argv.index("--")
        head, nb = argv[:k], argv[k + 1:]
    else:
        head, nb = argv, []
    try:
        if head[:1] == ["check"] and len(head) > 1:
            if nb:
                check(head[1:], parse(nb))
            return 0
        if head[:1] == ["select"] and len(head) in (2, 4) and (len(head) == 2 or head[2] == "--note"):
            note = head[3] if len(head) == 4 else None
            sys.stdout.write(to_yaml(select(head[1], parse(nb)) if nb else {}, note))
            return 0
    except (ParameterError, OSError) as e:
        print(f"{' '.join(str(e).split())}", file=sys.stderr)
        return 2
    print(usage, file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
