"""Generated blocks of the hand-written documents: every number the README (and any doc) quotes
from the figures' JSON is rendered here, between two marker lines, never typed.

A block in a Markdown file::

    <!-- generated: NAME (tiltpile docs; do not edit) -->
    ...
    <!-- end generated: NAME -->

``tiltpile docs`` (``make docs``, also run by ``make reports``) re-renders every block of the
files in ``FILES`` from the templates ``templates/<NAME>.md.j2`` with the main report's context
(:func:`tiltpile.report.main.context`) and the presets' table (:func:`presets`); ``--check``
changes nothing and exits 1 when a block is stale (the freshness test runs it). A block name
with no template, or a marker without its end, is an error naming the file and the line.
"""

from __future__ import annotations

import re
from pathlib import Path

from tiltpile import config as cfgmod
from tiltpile.outputs import replaced_whole

#: the documents that hold generated blocks, from the repository's root, and the prefix of the
#: templates their blocks are rendered from (``templates/<prefix>_<name>.md.j2``)
DOCUMENTS = {"README.md": "readme", "docs/presets.md": "presets", "docs/figures.md": "figures",
             "docs/dem.md": "dem", "docs/performance.md": "performance"}
FILES = tuple(DOCUMENTS)
BEGIN = re.compile(r"^<!-- generated: ([a-z0-9_-]+) \(tiltpile docs; do not edit\) -->$")
END = "<!-- end generated: {name} -->"


class BlockError(ValueError):
    """A document's generated block is malformed or names no template."""


def presets(root="figures") -> list[dict]:
    """One row per preset: its name, grains, history, engine, the runs of its ``make figures``,
    and its measured cost per run where a committed figure document holds it."""
    import json

    out = []
    for p in cfgmod.PRESET_TABLE:
        cfg = cfgmod.load(p.name)
        label = cfgmod.history_label(cfg.protocol.pretilt_deg) if cfg.protocol.pretilt_deg else "fresh"
        cost = {}
        base = Path(root).parent / p.figures
        for f in sorted(base.glob("fig2_*.json")) + sorted(base.glob(f"same-piles/{p.name}/fig2_*.json")):
            cost = json.loads(f.read_text()).get("cost") or {}
        step = cfg.protocol.pretilt_per_step_deg or cfg.protocol.tilt_per_step_deg
        rate = step / cfg.protocol.tilt_per_step_deg
        out.append({"name": p.name, "grains": cfg.scene.n, "runs": p.runs,
                    "history": ("fresh" if not cfg.protocol.pretilt_deg else
                                "cycled, at the ramp's rate" if rate == 1 else
                                f"cycled, {rate:g}x the ramp's rate"),
                    "label": label, "engine": "DEM" if cfg.dem is not None else "CD",
                    "sweeps": cost.get("sweeps_per_run"), "hours": (cost.get("seconds_per_run") or 0) / 3600
                    or None, "figures": p.figures})
    return out


def _environment():
    from .main import _environment as env

    return env()


def render_all(root="figures") -> dict[str, str]:
    """{block name: its Markdown} of every template ``templates/<prefix>_<name>.md.j2`` of a
    document's prefix (``DOCUMENTS``)."""
    from .main import context

    env = _environment()
    ctx = {**context(root), "presets": presets(root)}
    names = [n[:-len(".md.j2")] for n in env.list_templates() if n.endswith(".md.j2")
             and n.split("_")[0] in DOCUMENTS.values()]
    return {n: env.get_template(f"{n}.md.j2").render(**ctx).rstrip("\n") for n in names}


def fill(text: str, blocks: dict[str, str], where: str = "") -> str:
    """``text`` with every generated block replaced by ``blocks[name]`` (BlockError naming
    ``where`` and the line for an unknown name or a block without its end)."""
    lines = text.split("\n")
    out, i = [], 0
    while i < len(lines):
        m = BEGIN.match(lines[i])
        out.append(lines[i])
        if not m:
            i += 1
            continue
        name = m.group(1)
        if name not in blocks:
            raise BlockError(f"{where}:{i + 1}: generated block {name!r} has no template "
                             f"(known: {', '.join(sorted(blocks))})")
        end = END.format(name=name)
        try:
            j = lines.index(end, i + 1)
        except ValueError:
            raise BlockError(f"{where}:{i + 1}: generated block {name!r} has no end line "
                             f"{end!r}") from None
        out += blocks[name].split("\n") + [end]
        i = j + 1
    return "\n".join(out)


def update(repo=".", root="figures", check: bool = False) -> list[Path]:
    """Re-render every block of ``FILES`` under ``repo``; the files that changed (with ``check``,
    that would change: nothing is written). Each file is written whole or not at all."""
    repo = Path(repo)
    blocks = render_all(repo / root)
    changed = []
    for name in FILES:
        p = repo / name
        if not p.exists():
            continue
        old = p.read_text()
        new = fill(old, blocks, name)
        if new != old:
            changed.append(p)
            if not check:
                with replaced_whole(p) as tmp:
                    tmp.write_text(new)
    return changed
