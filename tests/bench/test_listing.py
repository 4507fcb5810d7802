"""``python -m benchmarks`` lists every module of the package, and the package's docstring
table names exactly those: a tool added without its line (as kill_resume once was), or a line
left behind by a removed study, fails here."""

from __future__ import annotations

import importlib
import importlib.util
import re

import benchmarks as bench
from benchmarks import __main__ as listing


def _table() -> list[str]:
    """The names of the docstring's table of tools (lines that start with ``name`` and a gap)."""
    return re.findall(r"^``(\w+)``\s{2,}\S", bench.__doc__, flags=re.M)


def test_the_table_names_every_tool_once():
    names = _table()
    assert len(names) == len(set(names)), names
    assert sorted(names) == bench.tools()


def test_every_tool_runs_as_a_module():
    """Each tool has ``main`` and runs under ``python -m`` (a module's ``__main__`` guard, a
    package's ``__main__`` module)."""
    for name in bench.tools():
        mod = importlib.import_module(f"benchmarks.{name}")
        assert callable(getattr(mod, "main", None)), f"benchmarks.{name} has no main(argv)"
        if hasattr(mod, "__path__"):  # found, not imported: importing it would run it
            assert importlib.util.find_spec(f"benchmarks.{name}.__main__"), name
        else:
            src = open(mod.__file__).read()
            assert re.search(r'^if __name__ == "__main__":', src, flags=re.M), name


def test_the_listing_is_the_package(capsys):
    listing.main()
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[2] for ln in lines] == [f"benchmarks.{n}" for n in bench.tools()]
    assert "benchmarks.kill_resume" in {ln.split()[2] for ln in lines}
    for ln, name in zip(lines, bench.tools()):
        assert ln.split(None, 3)[3] == listing.summary(name) != ""


def test_the_finished_studies_are_gone():
    """The studies the docstring says left the package are not in it."""
    gone = re.search(r"The finished studies \(([^)]*)\)", " ".join(bench.__doc__.split())).group(1)
    names = re.findall(r"``(\w+)``", gone)
    assert len(names) == 7 and not set(names) & set(bench.tools())
