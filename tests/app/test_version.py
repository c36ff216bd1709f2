"""The version comes from git and names the commit that runs (issue 14 point 12)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_version_names_the_commit_that_runs() -> None:
    head = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short=10", "HEAD"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    done = subprocess.run(
        [sys.executable, "-m", "app", "--version"], capture_output=True, text=True, cwd=ROOT
    )
    assert done.returncode == 0
    assert done.stdout.startswith("accelcal ")
    assert f"(git {head}" in done.stdout
    assert "+g" in done.stdout.split()[1] or ".dev" in done.stdout  # setuptools-scm's form
