"""Which tiltpile modules a piece of code imports, read from the source without importing it.

Shared by tests/test_layers.py (imports follow the layers) and tests/workflow/test_build_graph.py
(the Makefile names every module a figure's code imports). Imports inside functions count, as do
relative ones; ``from a.b import name`` counts as ``a.b.name`` when that is a module, else as
``a.b``.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"


def _modules() -> dict[str, Path]:
    out = {}
    for p in sorted((SRC / "tiltpile").rglob("*.py")):
        parts = list(p.relative_to(SRC).with_suffix("").parts)
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    return out


MODULES: dict[str, Path] = _modules()
"""{dotted name: path} of every module and package under src/tiltpile."""


def package_of(mod: str) -> list[str]:
    """The package a module's relative imports start from, as name parts."""
    parts = mod.split(".")
    return parts if MODULES[mod].name == "__init__.py" else parts[:-1]


def resolve(name: str) -> str:
    """The most specific module of ``name`` that exists (``a.b.func`` -> ``a.b``)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name


def imports(tree: ast.AST, here: list[str]) -> list[tuple[str, int]]:
    """(imported tiltpile module, line) for every import in ``tree``; ``here``: the package of
    the code (:func:`package_of`), for relative imports."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(resolve(a.name), node.lineno) for a in node.names if a.name.split(".")[0] == "tiltpile"]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(here[: len(here) - node.level + 1] + ([node.module] if node.module else []))
            if base.split(".")[0] != "tiltpile":
                continue
            for a in node.names:
                full = f"{base}.{a.name}"
                out.append((full if full in MODULES else resolve(base), node.lineno))
    return out


def imports_of(mod: str) -> list[tuple[str, int]]:
    """(imported tiltpile module, line) for every import statement of module ``mod``."""
    path = MODULES[mod]
    return imports(ast.parse(path.read_text(), str(path)), package_of(mod))
