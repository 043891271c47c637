"""What a validation report was made with: rodnet's version and commit, the versions of Python
and the numerical libraries, the machine and the date."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

import rodnet

LIBRARIES = ("numpy", "scipy", "numba", "matplotlib")
UNKNOWN = "unknown"


def git_commit(root: Path) -> tuple[str, bool | None]:
    """The commit checked out at ``root`` and whether tracked files differ from it; ``("unknown",
    None)`` outside a git checkout or without git."""
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        if head.returncode != 0:
            return UNKNOWN, None
        changed = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                  "--untracked-files=no"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return UNKNOWN, None
    return head.stdout.strip(), bool(changed.stdout.strip()) if changed.returncode == 0 else None


def cpu_model(cpuinfo: Path = Path("/proc/cpuinfo")) -> str:
    """The first ``model name`` of ``/proc/cpuinfo``; ``platform.processor()`` or ``"unknown"``
    where that file is missing."""
    try:
        for line in cpuinfo.read_text(errors="replace").splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and value.strip():
                return value.strip()
    except OSError:
        pass
    return platform.processor() or UNKNOWN


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return UNKNOWN


def environment() -> dict[str, object]:
    """The report's header fields (flat, JSON-ready)."""
    commit, dirty = git_commit(Path(rodnet.__file__).resolve().parents[1])
    return {
        "rodnet_version": rodnet.__version__,
        "git_commit": commit,
        "git_modified": dirty,
        "python": platform.python_version(),
        **{name: _version(name) for name in LIBRARIES},
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "cpu_model": cpu_model(),
        "date": datetime.datetime.now(datetime.timezone.utc).astimezone().isoformat(timespec="seconds"),
    }
