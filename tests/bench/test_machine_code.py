"""``bench.machine_code``: its normalization removes what differs between two compilations of the
same source and nothing else, and two dumps of one source are byte-identical and cover the sweep the presets run."""

from __future__ import annotations

from benchmarks import machine_code as mc

ONE = """\t.file\t"<string>"
\t.loc\t1 241 0
# a comment
\tmovabsq\t$_ZN8tiltpile3sim6solver13_sweep_storedB2v4B42c8tJTC, %rax
\tmovabsq\t$.bytes.9054547120212164613, %rdx
\t.size\t".const.missing Environment: _ZN08NumbaEnv5numbaB2v4B42c", 220
\tvmulsd\t%xmm1, %xmm0, %xmm0
\tmovabsq\t$/work/a/src/tiltpile/sim/solver.py, %rcx"""

TWO = """\t.file\t"<other>"
\t.loc\t1 250 0
\tmovabsq\t$_ZN8tiltpile3sim6solver13_sweep_storedB3v72B42c8tJTC, %rax
\tmovabsq\t$".bytes.-4783786815283479770", %rdx
\t.size\t".const.missing Environment: _ZN08NumbaEnv5numbaB3v72B42c", 221
\tvmulsd\t%xmm1, %xmm0, %xmm0
\tmovabsq\t$/tmp/b/src/tiltpile/sim/solver.py, %rcx"""


def test_normalize_removes_compilation_noise_only():
    assert mc.normalize(ONE) == mc.normalize(TWO)
    changed = TWO.replace("vmulsd", "vaddsd")
    assert mc.normalize(ONE) != mc.normalize(changed)
    reordered = TWO.replace("%xmm1, %xmm0", "%xmm0, %xmm1")
    assert mc.normalize(ONE) != mc.normalize(reordered)


def test_two_dumps_of_one_source_are_identical_and_hold_the_presets_sweep(tmp_path):
    """Two runs of the tool (each compiling afresh in its own cache) write the same file, and it
    lists the sweep the presets run and the step that calls it."""
    a, b = tmp_path / "a.s", tmp_path / "b.s"
    assert mc.main([str(a)]) == 0
    assert mc.main([str(b)]) == 0
    text = a.read_text()
    assert text == b.read_text()
    heads = [line.split(" ")[1] for line in text.splitlines() if line.startswith("=== ")]
    assert "tiltpile.sim.solver._sweep_stored" in heads
    assert "tiltpile.sim.step.advance" in heads
