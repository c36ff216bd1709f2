"""The command line starts light: `import app.cli` imports no GUI, hardware, file-format or
database library, and no scipy (issue 14 point 4; timing in bench/startup.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
HEAVY = (
    "PySide6",
    "pyqtgraph",
    "h5py",
    "reportlab",
    "nidaqmx",
    "pyvisa",
    "pyvisa_sim",
    "sqlalchemy",
    "alembic",
    "psycopg",
    "scipy",
)

pytestmark = pytest.mark.integration  # a fresh interpreter per test


def imported_by(code: str) -> list[str]:
    """Top-level packages of HEAVY that `code`, run in a fresh interpreter, imports."""
    probe = (
        f"{code}\nimport sys, json\n"
        f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & {set(HEAVY)!r})))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_import_app_cli_imports_no_heavy_library() -> None:
    assert imported_by("import app.cli") == []


def test_help_and_parsing_import_no_heavy_library() -> None:
    code = (
        "import contextlib, io\nfrom app import cli\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    cli.main(['--help'])\n"
        "    cli.build_parser().parse_args(['run', '--sim', '--dut', 'capacitive', '--level', '3'])"
    )
    assert imported_by(code) == []


def test_a_command_still_gets_its_errors_caught_by_kind(tmp_path: Path) -> None:
    """The errors of lazily imported modules map to their exit codes (2: bad input)."""
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an HDF5 file")
    done = subprocess.run(
        [sys.executable, "-m", "app", "analyze", str(bad)], cwd=ROOT, capture_output=True, text=True
    )
    assert done.returncode == 2, done.stderr
    assert "error:" in done.stderr
