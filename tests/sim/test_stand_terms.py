"""The FB-4 stand file's terms above 2 kHz and its CMC there are what bench/stand_terms.py
prints today (sim.true_stand.characterised_terms: the laboratory's type B evaluation), not
numbers edited by hand."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
STAND = ROOT / "sim" / "stand-fixture4-physics.toml"


@pytest.mark.slow
def test_the_stand_file_holds_the_characterised_terms_as_printed(tmp_path: Path) -> None:
    script = ROOT / "bench" / "stand_terms.py"
    done = subprocess.run(
        [sys.executable, str(script), "--check", str(STAND)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "transverse motion (rocking mode), phase" in done.stdout
    # a hand-edited value is caught
    edited = tmp_path / "stand.toml"
    edited.write_text(STAND.read_text(encoding="utf-8").replace("[5000.0, 0.63]", "[5000.0, 0.3]"))
    assert edited.read_text(encoding="utf-8") != STAND.read_text(encoding="utf-8")
    done = subprocess.run(
        [sys.executable, str(script), "--check", str(edited)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 1 and "does not hold these blocks" in done.stderr
