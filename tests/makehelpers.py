"""What the tests that run ``make`` share."""

from __future__ import annotations

import os

# make as a user types it: the suite itself runs under `make test`, whose MAKELEVEL and MAKEFLAGS
# would make these makes print "Entering directory" lines and inherit its flags
MAKE_ENV = {k: v for k, v in os.environ.items()
            if k not in ("MAKELEVEL", "MAKEFLAGS", "MFLAGS", "MAKEOVERRIDES")}


def papermill_one_cell(tmp_path, source: str):
    """Run a one-cell notebook of ``source`` through papermill on the tiltpile kernel, as the
    build does; (the finished process, the executed notebook as JSON). Skips without the
    kernel (make setup installs it)."""
    import json
    import subprocess
    import sys

    import pytest
    from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel

    try:
        KernelSpecManager().get_kernel_spec("tiltpile")
    except NoSuchKernel:
        pytest.skip("no tiltpile kernel installed (make setup installs it)")
    nb = {"cells": [{"cell_type": "code", "execution_count": None, "id": "c0", "metadata": {},
                     "outputs": [], "source": source}],
          "metadata": {"kernelspec": {"name": "tiltpile", "display_name": "tiltpile",
                                      "language": "python"}},
          "nbformat": 4, "nbformat_minor": 5}
    src, out = tmp_path / "in.ipynb", tmp_path / "out.ipynb"
    src.write_text(json.dumps(nb))
    done = subprocess.run([sys.executable, "-m", "papermill", "--kernel", "tiltpile",
                           "--no-progress-bar", str(src), str(out)],
                          capture_output=True, text=True, timeout=300)
    return done, (json.loads(out.read_text()) if out.exists() else None)


def make_dry(*args, cwd=None, env=None, timeout=120):
    """``make -n ARGS`` as a user types it (``MAKE_ENV``), in ``cwd`` (default the repository's
    root): the finished process, its output as text (what make would run, or its one-line error)."""
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    return subprocess.run(["make", "-n", *args], cwd=cwd or root, capture_output=True, text=True,
                          timeout=timeout, env=env or MAKE_ENV)
