"""Logging: --verbose shows a run's run.log lines on stderr; an unexpected error is one line for
the user and its traceback is kept in the log file that line names."""

from __future__ import annotations

from pathlib import Path

import pytest

from app import cli


def test_verbose_shows_what_the_run_log_holds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "runs"
    argv = ["--verbose", "run", "--sim", "--periods", "3", "--out", str(out), "--json"]
    assert cli.main(argv) == 0
    err = capsys.readouterr().err
    (folder,) = out.iterdir()
    lines = [line.split(" ", 1)[1] for line in (folder / "run.log").read_text().splitlines()]
    assert len(lines) > 5
    for line in lines:
        assert f"accelcal.run: {line}" in err
    assert cli.main(["run", "--sim", "--periods", "3", "--out", str(out), "--json"]) == 0
    assert "accelcal.run:" not in capsys.readouterr().err  # quiet without --verbose


def test_an_unexpected_error_is_one_line_and_its_traceback_is_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    log = tmp_path / "logs" / "accelcal.log"
    monkeypatch.setenv("ACCELCAL_LOG", str(log))

    def broken(args: object) -> int:
        raise RuntimeError("boom in the plan")

    monkeypatch.setitem(cli.COMMANDS, "plan", broken)
    assert cli.main(["plan"]) == 1
    err = capsys.readouterr().err
    assert err == f"accelcal plan: failed: RuntimeError: boom in the plan (traceback in {log})\n"
    kept = log.read_text()
    assert "Traceback (most recent call last)" in kept and "in broken" in kept
    assert "RuntimeError: boom in the plan" in kept
