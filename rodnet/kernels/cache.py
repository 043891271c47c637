"""Keep numba's on-disk cache of the compiled kernels consistent with their sources.

numba caches a compiled function (``cache=True``) under a stamp of the function's own source
file only. A kernel that calls a function of another module (the rods' contact loop calls the rod
element forces of :mod:`rodnet.kernels.cosserat_compiled`) or reads another module's constant
(:data:`rodnet.kernels.tension.REVERSED_STIFFNESS`) is compiled with that code frozen in: after
an edit of the other module alone, numba would go on loading the old machine code, and the run
would silently compute with the old physics.

:func:`refresh` (called when :mod:`rodnet` is imported) guards against that: it hashes the
sources of every module the kernels are built from (:data:`SOURCES`) into one digest, keeps it in
a stamp file beside each cache directory, and when the digest differs from the stamp it deletes
the cached kernels of those modules, so that numba compiles them afresh on their first call.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from numba.core import event

PACKAGE = Path(__file__).resolve().parents[1]

SOURCES: tuple[Path, ...] = (*sorted((PACKAGE / "kernels").glob("*.py")),
                             PACKAGE / "contact" / "mesh_distance.py",
                             PACKAGE / "contact" / "rigid_body.py")
"""Every module with compiled kernels, and every module whose functions or constants they use."""

STAMP = "rodnet-kernels.sha256"
"""The stamp file's name in a cache directory."""


def digest(sources: tuple[Path, ...] | list[Path]) -> str:
    """The SHA-256 of the sources' names and contents, in the given order."""
    h = hashlib.sha256()
    for path in sources:
        h.update(path.name.encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


def cache_directories(sources: tuple[Path, ...] | list[Path]) -> list[Path]:
    """Where numba may keep the cache of functions defined in ``sources``: ``NUMBA_CACHE_DIR``'s
    mirror of the source folder, the ``__pycache__`` beside it, and the user-wide cache (numba
    takes the first that works; all that exist are checked)."""
    found: list[Path] = []
    try:
        from numba.core import config
        from numba.core.caching import _CacheLocator
        from numba.misc.appdirs import AppDirs
    except ImportError:  # another numba layout: only the cache beside the sources
        config = _CacheLocator = AppDirs = None  # type: ignore[assignment]
    for folder in sorted({path.parent for path in sources}):
        candidates = [folder / "__pycache__"]
        try:  # stamped before numba writes to it, so its first kernels are not taken as stale
            candidates[0].mkdir(exist_ok=True)
        except OSError:
            pass
        if _CacheLocator is not None:
            sub = _CacheLocator.get_suitable_cache_subpath(str(folder / "x.py"))
            if config.CACHE_DIR:
                candidates.append(Path(config.CACHE_DIR) / sub)
            candidates.append(Path(AppDirs(appname="numba", appauthor=False).user_cache_dir) / sub)
        found += [c for c in candidates if c.is_dir()]
    return found


def refresh(sources: tuple[Path, ...] | list[Path] = SOURCES,
            directories: list[Path] | None = None) -> list[Path]:
    """Delete the cached kernels of ``sources`` in every cache directory whose stamp is not the
    sources' current digest, then stamp it; returns the files deleted.

    A cache file belongs to a source when its name starts with the source's module name and a
    dot (numba names them ``<module>.<function>-<line>.py<ver>.nbi`` / ``.nbc``). Directories
    that cannot be written are left as they are.
    """
    current = digest(sources)
    stems = {path.stem for path in sources}
    removed: list[Path] = []
    for folder in cache_directories(sources) if directories is None else directories:
        stamp = folder / STAMP
        try:
            if stamp.is_file() and stamp.read_text().strip() == current:
                continue
            for entry in folder.iterdir():
                if entry.suffix in (".nbi", ".nbc") and entry.name.split(".", 1)[0] in stems:
                    entry.unlink()
                    removed.append(entry)
            temporary = folder / f"{STAMP}.{os.getpid()}"
            temporary.write_text(current + "\n")
            temporary.replace(stamp)
        except OSError:  # read-only install, or another process cleaning at the same time
            continue
    return removed


@contextmanager
def compile_timer() -> Iterator[Callable[[], float]]:
    """Time numba's compiling inside the block: yields a function that returns the wall seconds
    spent compiling so far (a compile nested in another counted once; loading a cached kernel
    is not compiling)."""
    listener = event.TimingListener()
    with event.install_listener("numba:compile", listener):
        yield lambda: listener.duration if listener.done else 0.0
