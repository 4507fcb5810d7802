"""The map stays true (docs/architecture.md): every package's docstring names each of its modules,
and every file the page names exists, the recipes' file lists with the names they cite in each.

A package's modules are its ``.py`` files (``__init__`` and ``__main__`` aside) and its
subpackages, read from the source tree, so that a module added or removed is seen here. The
measurements, ``benchmarks/`` beside the package, name every module as a tool in their table,
and the package never imports them (they are not installed with it).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from importgraph import MODULES, imports_of

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "src" / "tiltpile"
MAP = ROOT / "docs" / "architecture.md"
PACKAGES = sorted(p.parent for p in PKG.rglob("__init__.py") if "__pycache__" not in p.parts)
BENCH = ROOT / "benchmarks"   # the measurements, beside the package (not installed)
BENCH_PACKAGES = sorted(p.parent for p in BENCH.rglob("__init__.py") if "__pycache__" not in p.parts)


def modules_of(pkg: Path) -> list[str]:
    """The modules of package directory ``pkg``: its .py files and its subpackages."""
    files = [p.stem for p in pkg.glob("*.py") if p.stem not in ("__init__", "__main__")]
    subs = [d.name for d in pkg.iterdir() if (d / "__init__.py").is_file()]
    return sorted(files + subs)


def docstring(pkg: Path) -> str:
    return ast.get_docstring(ast.parse((pkg / "__init__.py").read_text())) or ""


def names(doc: str, name: str) -> bool:
    """Whether ``doc`` names module ``name`` as code: ``name``, ``name.attr``, :mod:`.name`,
    ``pkg.name``, ``name/``."""
    return re.search(rf"(?:``|`|\.){re.escape(name)}(?:``|`|\.|\(|/)", doc) is not None


def _dotted(pkg: Path) -> str:
    base = BENCH.parent if pkg.is_relative_to(BENCH) else PKG.parent
    return ".".join(pkg.relative_to(base).parts)


@pytest.mark.parametrize("pkg", PACKAGES + BENCH_PACKAGES, ids=_dotted)
def test_every_package_docstring_names_its_modules(pkg):
    doc = docstring(pkg)
    missing = [m for m in modules_of(pkg) if not names(doc, m)]
    assert not missing, f"{_dotted(pkg)}'s docstring ({pkg.relative_to(ROOT)}/__init__.py) " \
                        f"does not name {missing}"


def _bench_tools(doc: str) -> list[str]:
    """The modules the benchmarks docstring's table names: the ``name`` that starts a line."""
    return re.findall(r"^``(\w+)``\s{2,}\S", doc, flags=re.M)


def test_the_benchmarks_table_names_every_tool_and_only_those():
    """Every module of benchmarks/ is a live tool with a row in its docstring's table (the
    finished studies left the package; notes/performance-log.md gives their commit)."""
    mods = set(modules_of(BENCH))
    tools = _bench_tools(docstring(BENCH))
    assert set(tools) == mods, (f"benchmarks/__init__.py's table names {sorted(set(tools) - mods)} that "
                                f"are not there and misses {sorted(mods - set(tools))}")
    assert not names("``pile``  the piles", "timing") and names(":mod:`.timing`", "timing")
    assert names("``chart`` (``spec``, ``plots``)", "spec") and not names("inspect the spec", "spec")


def test_the_package_does_not_import_the_benchmarks():
    """benchmarks/ is not installed: nothing in src/tiltpile may import it."""
    wrong = sorted(str(p.relative_to(ROOT)) for p in PKG.rglob("*.py")
                   if re.search(r"^\s*(from|import) benchmarks\b", p.read_text(), flags=re.M))
    assert not wrong, f"{wrong} import benchmarks, which is not installed with tiltpile"


# ------------------------------------------------------------------------------------------------
# docs/architecture.md

TEXT = MAP.read_text()
ROOTS = ("src/", "benchmarks/", "tests/", "docs/", "notebooks/", "figures/", "paper/", "examples/")
TOP_FILES = ("Makefile", "README.md", "CHANGELOG.md", "pyproject.toml", "environment.txt")


def _section(heading: str) -> str:
    start = TEXT.index(f"\n## {heading}\n")
    end = TEXT.find("\n## ", start + 1)
    return TEXT[start:end if end > 0 else None]


def _recipes() -> dict[str, str]:
    parts = re.split(r"^### (.+)$", _section("Recipes"), flags=re.M)
    return dict(zip(parts[1::2], parts[2::2]))


def existing(path: str) -> list[Path]:
    """The files or directories ``path`` stands for: itself, or with each ``<...>`` a wildcard
    (a new file of a recipe is named after the ones it joins, so some must exist)."""
    if "<" not in path and "*" not in path:
        p = ROOT / path
        return [p] if p.exists() else []
    pattern = re.sub(r"<[^>]*>", "*", path).rstrip("/")
    return sorted(ROOT.glob(pattern))


def _is_path(token: str) -> bool:
    return token.startswith(ROOTS) or token in TOP_FILES


def _file_lists(body: str) -> list[tuple[str, list[str]]]:
    """(path, [names cited after it]) of each bullet of the recipe's "**Files it touches:**"."""
    block = body.split("**Files it touches:**", 1)[1].split("\n**", 1)[0]
    out = []
    for bullet in re.split(r"\n(?=- )", block.strip()):
        tokens = re.findall(r"`([^`]+)`", bullet)
        assert bullet.startswith("- `") and tokens and _is_path(tokens[0]), bullet
        out.append((tokens[0], [t for t in tokens[1:] if re.fullmatch(r"[A-Za-z_]\w*", t)]))
    return out


def test_the_map_has_every_recipe_and_each_says_its_files_and_its_records():
    recipes = _recipes()
    for want in ("Add an observable", "Add a figure", "Add a claim", "Add a preset",
                 "Change analysis code without stranding the records"):
        assert want in recipes, f"docs/architecture.md has no recipe '{want}'"
    for title, body in recipes.items():
        assert "**Files it touches:**" in body, title
        assert "**The records:**" in body, title
        assert _file_lists(body), title


@pytest.mark.parametrize("title", list(_recipes()))
def test_each_recipes_files_exist_and_hold_what_it_names(title):
    """Every file a recipe lists exists (a new one: files of its kind do), and each name it cites
    beside a file (``PRESETS``, ``READS``, ...) is in that file."""
    for path, cited in _file_lists(_recipes()[title]):
        found = existing(path)
        assert found, f"'{title}' lists {path}, which does not exist"
        files = [f for p in found for f in ([p] if p.is_file() else sorted(p.rglob("*")))
                 if f.is_file()]
        for name in cited:
            assert any(re.search(rf"\b{name}\b", f.read_text(errors="ignore")) for f in files), \
                f"'{title}': {path} has no {name}"


def test_every_path_the_map_names_exists():
    paths = sorted({t for t in re.findall(r"`([^`\s]+)`", TEXT) if _is_path(t)})
    assert len(paths) > 30
    missing = [p for p in paths if not existing(p)]
    assert not missing, f"docs/architecture.md names paths that do not exist: {missing}"


def test_the_map_names_every_layer_and_the_docs_link_it():
    import tiltpile

    layers = _section("The layers")
    for k, parts in enumerate(tiltpile.LAYERS[:-1]):      # the last layer: python -m tiltpile
        row = next((line for line in layers.splitlines() if line.startswith(f"| {k} |")), None)
        assert row is not None, f"docs/architecture.md has no row of layer {k}"
        assert re.findall(r"`(\w+)`", row.split("|")[2]) == list(parts), (k, row)
    readme = (ROOT / "README.md").read_text()
    assert "(docs/architecture.md)" in readme
    assert "(architecture.md)" in (ROOT / "docs" / "README.md").read_text()


def test_the_path_check_bites():
    assert existing("src/tiltpile/figures/fig<N>.py") and existing("src/tiltpile/config.py")
    assert not existing("src/tiltpile/figures/nofig<N>.py") and not existing("src/tiltpile/no.py")
    files = _file_lists("x\n**Files it touches:**\n\n- `Makefile`: `RUNS_<n>`, `FIG_COMMON`\n"
                        "- `src/tiltpile/config.py` (or `other.py`): `PRESETS`\n\n**The records:** y")
    assert files == [("Makefile", ["FIG_COMMON"]), ("src/tiltpile/config.py", ["PRESETS"])]


def _slug(heading: str) -> str:
    """GitHub's anchor of a markdown heading: lower case, punctuation but - and _ dropped,
    spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def broken_links(md: Path) -> list[str]:
    """The relative links of markdown file ``md`` whose file, or whose #anchor in a markdown
    file, does not exist."""
    text = md.read_text()
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target):                       # http:, mailto: ...
            continue
        path, _, anchor = target.partition("#")
        dest = (md.parent / path).resolve() if path else md
        if not dest.exists():
            broken.append(target)
        elif anchor and dest.suffix == ".md":
            heads = re.findall(r"^#+ (.+)$", dest.read_text(), flags=re.M)
            if anchor not in {_slug(h) for h in heads}:
                broken.append(target)
    return broken


def test_the_readme_is_a_users_guide_of_at_most_150_lines_whose_links_resolve():
    """At most 150 lines; its first command is the few-minute one; its first link to a report
    is the main report, which leads with the paper's scale; every link resolves."""
    readme = ROOT / "README.md"
    text = readme.read_text()
    assert len(text.splitlines()) <= 150
    first = re.search(r"^make \S+.*$", text, flags=re.M).group(0)
    assert first.startswith("make figures PRESET=smoke"), first
    assert re.search(r"\]\(([^)]*REPRODUCTION\.md)\)", text).group(1) == "paper/REPRODUCTION.md"
    assert broken_links(readme) == []


def test_the_link_check_bites(tmp_path):
    (tmp_path / "a.md").write_text("# Install without make\n")
    (tmp_path / "b.md").write_text("[x](a.md#install-without-make) [y](a.md#install) "
                                   "[z](c.md) [w](https://example.org/c.md)\n")
    assert broken_links(tmp_path / "b.md") == ["a.md#install", "c.md"]
