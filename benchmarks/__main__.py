"""``python -m benchmarks``: list the measurement modules (``benchmarks.tools()``, every
module of the package) and the first paragraph of each one's docstring."""

import importlib

from benchmarks import tools


def summary(name: str) -> str:
    """The first paragraph of the docstring of ``benchmarks.<name>``, on one line."""
    doc = importlib.import_module(f"benchmarks.{name}").__doc__ or ""
    return " ".join(doc.strip().split("\n\n")[0].split())


def main() -> None:
    for name in tools():
        print(f"python -m benchmarks.{name:18s} {summary(name)}")


if __name__ == "__main__":
    main()
