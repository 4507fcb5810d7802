"""``python -m tiltpile.bench``: list the measurement modules and the first line of each one's docstring."""

import importlib

from tiltpile.bench import STUDIES

for name in STUDIES:
    try:
        doc = (importlib.import_module(f"tiltpile.bench.{name}").__doc__ or "").strip().splitlines()[0]
    except ModuleNotFoundError:
        continue
    print(f"python -m tiltpile.bench.{name:18s} {doc}")
