"""The `tiltpile` Jupyter kernel that `make setup` installs runs a notebook through papermill's
command line, as `make figures` does, and its start leaves no log lines in the build's output
(ipykernel >= 7.3 warns at every start that its loopback sockets are unencrypted)."""

from __future__ import annotations


def test_the_kernel_runs_a_notebook_quietly(tmp_path):
    from makehelpers import papermill_one_cell

    done, executed = papermill_one_cell(tmp_path, "print(6 * 7)")
    assert done.returncode == 0, done.stderr
    cell = executed["cells"][-1]
    assert cell["outputs"][0]["text"] == ["42\n"]
    assert "IPKernelApp" not in done.stderr, done.stderr
