"""The house keeps its shape: imports follow the layers declared in ``tiltpile.LAYERS``.

Every ``import tiltpile...`` in src/tiltpile (at module level or inside a function) is read
from the source, without importing anything. A module may import from its own subpackage (or
module) and from any layer below its own; ``tiltpile`` itself only for ``__version__``.
"""

from __future__ import annotations

import pytest
from importgraph import MODULES, imports_of

import tiltpile


def part(mod: str) -> str:
    """The top-level part of tiltpile a module belongs to (``tiltpile.sim.step`` -> ``sim``)."""
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else "tiltpile"


LAYER_OF = {name: k for k, layer in enumerate(tiltpile.LAYERS) for name in layer}


def test_every_part_of_the_package_is_in_a_layer():
    parts = {part(m) for m in MODULES} - {"tiltpile"}
    missing = sorted(parts - set(LAYER_OF))
    assert not missing, f"add {missing} to tiltpile.LAYERS (src/tiltpile/__init__.py)"
    assert not sorted(set(LAYER_OF) - parts), "tiltpile.LAYERS names parts that do not exist"


@pytest.mark.parametrize("mod", sorted(m for m in MODULES if part(m) != "tiltpile"))
def test_imports_point_down(mod):
    me = part(mod)
    wrong = []
    for target, line in imports_of(mod):
        other = part(target)
        if other == me:
            continue
        if other == "tiltpile":  # the package itself: only its __version__
            continue
        if LAYER_OF.get(other, -1) >= LAYER_OF.get(me, -1):
            wrong.append(f"line {line}: {target} (layer {LAYER_OF.get(other)}: {other})")
    assert not wrong, (f"{mod} (layer {LAYER_OF.get(me)}: {me}) imports from its own layer or "
                       f"above: {wrong}; see tiltpile.LAYERS")


def test_the_package_root_imports_nothing():
    assert imports_of("tiltpile") == []


def test_sim_imports_nothing_outside_sim():
    for mod in (m for m in MODULES if part(m) == "sim"):
        assert {part(t) for t, _ in imports_of(mod)} <= {"sim"}, mod


def test_no_import_circle():
    """No chain of imports (module level or inside functions) leads from a module back to itself."""
    graph = {m: {t for t, _ in imports_of(m)} - {m} for m in MODULES}
    state: dict[str, int] = {}
    circles = []

    def visit(u, stack):
        state[u] = 1
        stack.append(u)
        for v in sorted(graph[u]):
            if state.get(v) == 1:
                circles.append(" -> ".join(stack[stack.index(v):] + [v]))
            elif v not in state:
                visit(v, stack)
        stack.pop()
        state[u] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])
    assert not circles, circles
