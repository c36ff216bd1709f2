"""`--resonance` in a run of several DUTs (issue 36, stop 42's leftover): every DUT's
mounted resonance is searched in its own response, not the first DUT's alone, and each is
printed with its DUT: a loosely mounted DUT beside a well mounted one (sim/models.py's
"loose", its mount resonance 1.2 kHz inside the plan) is found at its own resonance."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from app.cli import main
from app.records.batch import read_batch

pytestmark = pytest.mark.integration

STAND = Path(__file__).parents[3] / "sim" / "stand-fixture4.toml"


def test_resonance_is_searched_for_every_dut_of_the_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ACCELCAL_DATA_DIR", str(tmp_path / "data"))
    argv = ["run", "--stand", str(STAND), "--dut", "A=SN-A", "--dut", "C=SN-C",
            "--dut-model", "C=loose", "--seed", "5", "--periods", "3",
            "--technician", "A. Tech", "--resonance"]  # fmt: skip
    assert main(argv) in (0, 1), capsys.readouterr().err
    printed = capsys.readouterr().out
    (batch,) = [p for p in (tmp_path / "runs").iterdir() if (p / "batch.json").exists()]
    members = read_batch(batch).members
    assert [m.position for m in members] == ["A", "C"]
    searches = []
    for member in members:
        results = json.loads((tmp_path / "runs" / member.run_id / "results.json").read_text())
        search = results["results"].get("resonance")
        assert search is not None, member.position  # searched in this DUT's own response
        searches.append(search)
    assert not searches[0]["found"]  # the well mounted piezo: none up to the plan's top
    assert searches[1]["found"]  # the loose one: its mount resonance, within its U
    f0 = searches[1]["frequency_hz"]
    assert abs(f0 - 1200.0) <= searches[1]["frequency_expanded_hz"]
    # printed after each DUT's results, as a single run prints it
    sections = printed.split("--- position ")[1:]
    assert [s.split(":")[0] for s in sections] == ["A", "C"]
    assert "\nresonance: not found within the plan" in sections[0]
    assert "\nresonance: f0 = (" in sections[1]
