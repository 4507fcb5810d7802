"""Adding an observable, shown in one figure and judged by one claim, takes three hand-edited
files (docs/architecture.md, "Add an observable, a figure number and a claim"): in a scratch copy
of src/, the column and its producer (analysis/tables.py), the figure that reads it and reports a
number of it (figures/fig1.py), and the claim that judges that number (report/paper.py: its judge
returns a Judgement, and until its sentences are written in report/templates/claims.md.j2 the
report prints its values). What follows is generated: the column's golden values, the figure's
JSON, the report's line.

Run on a copy of the tests' smoke runs (their observables computed by the copy's code, so that
the session's caches stay those of this tiltpile).
"""

from __future__ import annotations

import filecmp
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from codehelpers import add_column, edit

ROOT = Path(__file__).resolve().parents[2]

FIG1_READS = ('"theta_m", "theta_to_onset"),', '"theta_m", "theta_to_onset", "n_wall_contacts"),')
FIG1_NUMBER = ('    numbers["snapshot"] = {"seed": seed, "frame": frame,',
               '    numbers["wall_contacts_mean"] = _mean(f["n_wall_contacts"])\n'
               '    numbers["snapshot"] = {"seed": seed, "frame": frame,')
CLAIM = '''

def _wall_contacts(n: dict) -> Judgement:
    mean = num(n.get("wall_contacts_mean"))
    return Judgement("wall_contacts", verdict_of(mean > 0, math.isfinite(mean)),
                     "on_walls" if mean > 0 else "off_walls", {"mean": mean})


CLAIMS_123.append(Claim(
    "wall_contacts", "The pile rests on its walls (a worked example)", "> 0", "fig1",
    _wall_contacts, Rule("(none: an example)", "agrees if the mean is above zero")))
'''

CHILD = r"""
import json, sys
from pathlib import Path
sys.path.insert(0, sys.argv[4])
import golden
from tiltpile.analysis import compute_observables
from tiltpile.figures import build
from tiltpile.report.claims import CLAIMS

data, figs = Path(sys.argv[1]), Path(sys.argv[2])
compute_observables(data, workers=1, progress=False)
numbers = build.build("fig1", data, "smoke", figs)
claim = next(c for c in CLAIMS if c.key == "wall_contacts")
j = claim.judge(json.loads((figs / "fig1_isostaticity.json").read_text())["numbers"])
values, codes = golden.compute()
want, want_codes = golden.load()
print(json.dumps({"number": numbers["wall_contacts_mean"], "verdict": j.verdict, "reason": j.reason,
                  "values": j.values, "ours": j.ours, "note": j.note,
                  "golden": golden.differences(values, codes, want, want_codes)}))
"""


@pytest.mark.slow
def test_an_observable_in_one_figure_and_one_claim_takes_three_files(smoke_ensemble, tmp_path):
    src = tmp_path / "src"
    shutil.copytree(ROOT / "src" / "tiltpile", src / "tiltpile",
                    ignore=shutil.ignore_patterns("__pycache__"))
    # the three hand-edited files
    add_column(src)
    edit(src / "tiltpile" / "figures" / "fig1.py", *FIG1_READS)
    edit(src / "tiltpile" / "figures" / "fig1.py", *FIG1_NUMBER)
    paper = src / "tiltpile" / "report" / "paper.py"
    text = paper.read_text()
    start = text.index("\n# ------", text.index("CLAIMS_123.append(Claim("))
    paper.write_text(text[:start] + CLAIM + text[start:])
    cmp = filecmp.dircmp(ROOT / "src" / "tiltpile", src / "tiltpile", ignore=["__pycache__"])

    def changed(d, prefix=""):
        out = [prefix + f for f in d.diff_files + d.left_only + d.right_only]
        for name, sub in d.subdirs.items():
            out += changed(sub, f"{prefix}{name}/")
        return out
    assert sorted(changed(cmp)) == ["analysis/tables.py", "figures/fig1.py", "report/paper.py"]

    data = tmp_path / "data"
    data.mkdir()
    for run in sorted(smoke_ensemble.glob("run_*.h5")):
        shutil.copy2(run, data / run.name)
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    r = subprocess.run([sys.executable, "-c", CHILD, str(data), str(tmp_path / "figs"), str(src),
                        str(ROOT / "tests" / "analysis")],
                       env=env, capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads(r.stdout.splitlines()[-1])
    assert got["number"] > 0 and got["verdict"] == "agrees", got
    assert got["reason"] == "on_walls" and got["values"] == {"mean": got["number"]}, got
    assert got["ours"].startswith("mean = ") and got["note"] == "", got   # no sentences written
    # the new column is the only thing the golden values lack: `golden.py --update` writes it
    assert got["golden"] == {"values": [], "codes": [], "missing": ["frames.n_wall_contacts"],
                             "gone": []}
