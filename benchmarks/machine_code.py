"""The machine code numba compiles for the simulator's kernels, normalized, so that two versions
of ``sim/`` can be compared without a quiet core: identical code runs at identical speed.

Usage: ``python -m benchmarks.machine_code OUT`` writes the x86-64 assembly of every compiled
signature of every kernel of ``sim/solver.py`` and ``sim/step.py`` after a short tilt of a smoke
pile (so every signature the presets use is compiled) to OUT, one ``=== module.kernel
signature`` header per listing, and prints one line per kernel. It compiles everything afresh,
in a child process with an empty numba cache of its own. Run it in two checkouts (or with
``PYTHONPATH`` at a ``git archive`` of the other commit) and ``cmp`` the two files: equal files
mean the edit changed no instruction.

What is normalized away is what differs from one compilation of the same source to the next:
the source file's path and line records (``.file``, ``.loc``), comments, numba's per-process
specialization counters in mangled names (``B2v4B`` -> ``BvB``), its hashed names of constant
byte strings (``.bytes.<hash>``) and the size directives of the error messages that quote those
mangled names. Two dumps of one source in fresh caches are byte-identical after it (checked when
this tool was written; ``tests/bench/test_machine_code.py`` checks the normalization).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile

_CHILD = "TILTPILE_MACHINE_CODE_CHILD"

_DROP_PREFIXES = (".file", ".loc", ".ident", "#")


def normalize(asm: str) -> str:
    """The listing without what changes between compilations of the same source (docstring)."""
    lines = []
    for line in asm.splitlines():
        s = line.strip()
        if s.startswith(_DROP_PREFIXES):
            continue
        if s.startswith(".size") and "missing Environment" in s:
            continue
        line = re.sub(r"/[^ \"]*\.py", "PATH", line)
        line = re.sub(r"B\d+v\d+B", "BvB", line)
        line = re.sub(r'"?\.bytes\.-?\d+(\.\d+)?"?', ".bytes.H", line)
        lines.append(line)
    return "\n".join(lines)


def listings(n_steps: int = 30) -> list[tuple[str, str]]:
    """[(header, normalized assembly)] of every compiled kernel signature of ``sim.solver`` and
    ``sim.step``, after ``n_steps`` tilt steps of the 60-grain bench pile (smoke preset).

    Only kernels this process compiled are listed: one loaded whole from numba's cache carries
    its callees' code without compiling them. ``main`` therefore runs it in a child process with
    an empty cache directory of its own."""
    from benchmarks.pile import bench_config, settled_pile
    from tiltpile.sim import solver, step

    cfg = bench_config(60, "smoke", None, ())
    system = settled_pile(cfg, 0, False)
    system.advance(n_steps, 0.0, cfg.protocol.tilt_per_step_deg)
    out = []
    for mod in (solver, step):
        for name in sorted(vars(mod)):
            fn = getattr(mod, name)
            if not (hasattr(fn, "inspect_asm") and fn.signatures):
                continue
            for sig, asm in sorted(fn.inspect_asm().items(), key=str):
                out.append((f"{mod.__name__}.{name} {sig}", normalize(asm)))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.machine_code",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("out", help="the file the listings are written to")
    args = p.parse_args(argv)
    if not os.environ.get(_CHILD):   # a fresh numba cache, so that every kernel is compiled
        with tempfile.TemporaryDirectory(prefix="tiltpile-machine-code-") as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache, **{_CHILD: "1"})
            return subprocess.run([sys.executable, "-m", "benchmarks.machine_code",
                                   args.out], env=env).returncode
    items = listings()
    with open(args.out, "w") as f:
        for head, asm in items:
            f.write(f"=== {head}\n{asm}\n")
    for head, asm in items:
        print(f"{head.split(' ')[0]:40s} {asm.count(chr(10)) + 1:6d} lines")
    print(f"wrote {args.out}: {len(items)} compiled signatures")
    return 0


if __name__ == "__main__":
    sys.exit(main())
