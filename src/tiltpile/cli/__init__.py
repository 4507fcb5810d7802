"""Command line: ``tiltpile <command>`` (also ``python -m tiltpile``), one module per command.

Each module in this package registers its subcommand (``add_parser(subparsers)``) and
implements it (``run(args) -> int``); library modules keep only their Python API. Every command
validates its whole input first; on bad input it prints one line naming the problem and exits
with status 2, having written nothing, as it does for an output another process is writing
(``outputs.OutputBusy``: an ensemble's directory). Failures past validation are one line too, exit status 1:
a damaged or unusable run file (``store.RunFileError``, also another process writing the same
file), a failed write (a full disk: "no space left on device while writing FILE; rerun to
resume"), a health stop (``SimulationError``), an OS error naming its path.

Modules: ``_common`` (what every command shares: the configuration options, the seed type, the
error path), and one per command of ``COMMANDS``, named after it: ``simulate``, ``dem``,
``ensemble``, ``observables``, ``verify``, ``report``, ``info``, ``export``,
``movie``, ``repose``, ``zcount``, ``record``, ``same_piles`` (``tiltpile same-piles``),
``study``, ``definitions``, ``docs`` (``tiltpile docs``: the generated blocks of the README
and the docs) and ``import_`` (``tiltpile import``). docs/cli.md gives every command's options
(tests/workflow/test_cli_doc.py checks them against the parser).
``solver_study``: ``tiltpile solver-study``.
``stiffness_study``: ``tiltpile stiffness-study``.
``config``: ``tiltpile config`` (every configuration key, from ``config.describe_keys``).
``figure``: ``tiltpile figure NAME DATA`` (one figure from any data, ``figures.build``).
``presets``: ``tiltpile presets`` (the presets as scale x history x engine; the Makefile runs it
as ``python -m tiltpile.cli.presets``, which needs the standard library alone).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from tiltpile import config as cfgmod

COMMANDS = ("simulate", "dem", "ensemble", "observables", "verify", "report", "info", "export",
            "movie", "repose", "zcount", "record", "same-piles", "study", "definitions", "docs",
            "solver-study", "stiffness-study", "import", "config", "figure", "presets")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="tiltpile", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(f"tiltpile.cli.{name.replace('-', '_')}{'_' * (name == 'import')}").add_parser(sub)
    return p


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    if isinstance(e, OSError) and not str(e).startswith(("no space", "cannot")):
        from tiltpile.store import _describe_os_error

        where = " -> ".join(str(p) for p in (e.filename, e.filename2) if p is not None)
        text = f"{where + ': ' if where else ''}{_describe_os_error(e)}"
    return text


def _one_line_warnings(command: str) -> None:
    """Our RuntimeWarnings (health, a discarded .part) as ``tiltpile <command>: warning: ...``."""
    import warnings

    default = getattr(warnings.formatwarning, "tiltpile_default", warnings.formatwarning)

    def fmt(message, category, filename, lineno, line=None):
        if issubclass(category, RuntimeWarning) and "tiltpile" in str(filename):
            return f"tiltpile {command}: warning: {message}\n"
        return default(message, category, filename, lineno, line)

    fmt.tiltpile_default = default
    warnings.formatwarning = fmt


def _exit_if_hdf5_is_broken(status: int) -> None:
    """An HDF5 file whose writes failed (a disk filled by another process under a run) crashes
    HDF5 when it is closed, also at interpreter exit: leave at once, the line printed. What is on
    disk is resumed (and checked) by the next run."""
    from tiltpile import store

    if store._BROKEN:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    import warnings

    saved = warnings.formatwarning
    _one_line_warnings(args.command)
    try:
        return _run(args)
    finally:
        warnings.formatwarning = saved


def _run(args) -> int:
    from tiltpile.outputs import OutputBusy
    from tiltpile.sim.protocol import SimulationError
    from tiltpile.store import MixedConfigError, RunBusyError, RunExistsError, RunFileError

    try:
        return args.func(args)
    except BrokenPipeError:  # the reader went away (`tiltpile info RUN | head`): not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so that the interpreter's final flush stays quiet
        return 0
    except (cfgmod.ConfigError, RunBusyError, RunExistsError, MixedConfigError, OutputBusy) as e:  # refused: nothing was done
        print(f"tiltpile {args.command}: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except (RunFileError, SimulationError, OSError) as e:
        print(f"tiltpile {args.command}: error: {_one_line(e)}", file=sys.stderr)
        _exit_if_hdf5_is_broken(1)
        return 1
    except KeyboardInterrupt:
        print(getattr(args, "interrupted", "interrupted"), file=sys.stderr)
        return 130
