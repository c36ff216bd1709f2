"""The program's version: from git through setuptools-scm at install time (pyproject.toml),
and, when it runs from a git checkout, the commit it runs (and "dirty" when the checkout has
changes), so a record names exactly the code that made it. Light: no heavy imports."""

from __future__ import annotations

import functools
import subprocess
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

_ROOT = Path(__file__).resolve().parent.parent


@functools.cache
def software_version() -> str:
    """'0.1.dev94+g1a2b3c4' as installed, plus ' (git 1a2b3c4, dirty)' from a git checkout."""
    try:
        installed = version("accelcal")
    except PackageNotFoundError:
        installed = "unknown"
    commit = _git("rev-parse", "--short=10", "HEAD")
    if commit is None:
        return installed
    dirty = _git("status", "--porcelain", "--untracked-files=no")
    return f"{installed} (git {commit}{', dirty' if dirty else ''})"


def _git(*args: str) -> str | None:
    if not (_ROOT / ".git").exists():
        return None
    try:
        done = subprocess.run(
            ["git", "-C", str(_ROOT), *args], capture_output=True, text=True, timeout=5
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None
