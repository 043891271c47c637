"""The compiled-kernel cache is dropped when any source the kernels are built from changes."""

from __future__ import annotations

from pathlib import Path

from rodnet.kernels import cache


def _cache_files(folder: Path) -> list[Path]:
    files = [folder / "a.step-10.py311.nbi", folder / "a.step-10.py311.1.nbc",
             folder / "b.force-3.py311.nbi", folder / "b.force-3.py311.1.nbc"]
    for f in files:
        f.write_bytes(b"compiled")
    return files


def test_an_edit_of_one_source_drops_the_kernels_of_all(tmp_path: Path) -> None:
    """``a`` calls ``b``: numba would keep ``a``'s machine code after an edit of ``b`` alone."""
    a, b = tmp_path / "a.py", tmp_path / "b.py"
    a.write_text("from b import force\n")
    b.write_text("STIFFNESS = 1.0\n")
    folder = tmp_path / "__pycache__"
    folder.mkdir()
    other = folder / "other.kernel-1.py311.nbi"   # not one of the sources: never touched
    other.write_bytes(b"compiled")
    pyc = folder / "a.cpython-311.pyc"
    pyc.write_bytes(b"bytecode")

    first = _cache_files(folder)
    assert sorted(cache.refresh([a, b], [folder])) == sorted(first)   # no stamp yet: stale
    assert (folder / cache.STAMP).read_text().strip() == cache.digest([a, b])

    kept = _cache_files(folder)
    assert cache.refresh([a, b], [folder]) == []                      # sources unchanged
    assert all(f.exists() for f in kept)

    b.write_text("STIFFNESS = 2.0\n")                                  # edit b only
    assert sorted(cache.refresh([a, b], [folder])) == sorted(kept)    # a's kernels go too
    assert not any(f.exists() for f in kept)
    assert other.exists() and pyc.exists()


def test_the_package_sources_cover_the_modules_with_kernels() -> None:
    """Every module that compiles with ``cache=True`` is among the stamped sources."""
    package = cache.PACKAGE
    compiled = {p for p in package.rglob("*.py") if "cache=True" in p.read_text()}
    assert compiled, "no cached kernels found"
    assert compiled <= set(cache.SOURCES), sorted(str(p) for p in compiled - set(cache.SOURCES))
