"""The README's Python example of driving the simulator runs as written (a smoke pile to 2 deg)."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"


def _block(heading: str) -> str:
    text = README.read_text()
    section = text[text.index(heading):]
    return re.search(r"```python\n(.*?)```", section, flags=re.S).group(1)


def test_the_readme_drives_the_simulator(tmp_path, monkeypatch):
    from tiltpile.store import open_run

    code = _block("## Drive the simulator from Python")
    assert "protocol.run(" in code and "simulate(" in code
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "README.md", "exec"), {})
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("deposited in ") and any(x.startswith("frame 0: 0.00 deg") for x in lines)
    assert any(x.startswith("frame 20: 2.00 deg") for x in lines)
    assert any(x.startswith("ended (theta_max) at 2.00 deg") for x in lines)
    assert lines[-1].startswith("run.h5 ") and lines[-1].endswith("health warnings: []")
    with open_run(tmp_path / "run.h5") as run:
        assert run.seed == 1 and abs(float(run.theta_deg[-1]) - 2.0) < 1e-9
