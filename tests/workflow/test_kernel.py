"""The `tiltpile` Jupyter kernel that `make setup` installs runs a notebook through papermill's
command line, as `make figures` does, and its start leaves no log lines in the build's output
(ipykernel >= 7.3 warns at every start that its loopback sockets are unencrypted)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest


def test_the_kernel_runs_a_notebook_quietly(tmp_path):
    from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel

    try:
        KernelSpecManager().get_kernel_spec("tiltpile")
    except NoSuchKernel:
        pytest.skip("no tiltpile kernel installed (make setup installs it)")
    nb = {"cells": [{"cell_type": "code", "execution_count": None, "id": "c0", "metadata": {},
                     "outputs": [], "source": ["print(6 * 7)"]}],
          "metadata": {"kernelspec": {"name": "tiltpile", "display_name": "tiltpile",
                                      "language": "python"}},
          "nbformat": 4, "nbformat_minor": 5}
    src, out = tmp_path / "in.ipynb", tmp_path / "out.ipynb"
    src.write_text(json.dumps(nb))
    done = subprocess.run([sys.executable, "-m", "papermill", "--kernel", "tiltpile",
                           "--no-progress-bar", str(src), str(out)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    cell = json.loads(out.read_text())["cells"][-1]
    assert cell["outputs"][0]["text"] == ["42\n"]
    assert "IPKernelApp" not in done.stderr, done.stderr
