"""numba's cache is dropped when any sim source changes (it only checks a kernel's own file)."""

from tiltpile.sim import jit


def test_stale_cache_is_dropped_and_fresh_one_kept(tmp_path):
    (tmp_path / "step.advance-70.py311.nbi").write_text("old")
    (tmp_path / "step.advance-70.py311.1.nbc").write_text("old")
    (tmp_path / jit.STAMP).write_text("hash of older sources")
    (tmp_path / "keep.txt").write_text("not a numba file")
    assert jit.drop_stale_cache(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([jit.STAMP, "keep.txt"])
    assert (tmp_path / jit.STAMP).read_text() == jit.sources_hash()
    (tmp_path / "step.advance-70.py311.nbi").write_text("built from the current sources")
    assert not jit.drop_stale_cache(tmp_path)
    assert (tmp_path / "step.advance-70.py311.nbi").exists()


def test_cache_dir_follows_numba_cache_dir(monkeypatch, tmp_path):
    monkeypatch.setattr(jit.numba.config, "CACHE_DIR", str(tmp_path))
    assert jit.cache_dir().parent == tmp_path
    assert jit.cache_dir().name.startswith("sim_")
    monkeypatch.setattr(jit.numba.config, "CACHE_DIR", "")
    assert jit.cache_dir() == jit.SIM_DIR / "__pycache__"
