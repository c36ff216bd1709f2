"""The run's preflight is computed once per run (issue 34 point 6): `run.prepare` checks it
before the run folder exists and the procedure's `run()` uses the same report; the LPM's
record run takes the fade-in the preflight picked instead of picking it again. Each
computation is a synthesis of the plan's motion and its fades (at 51.2 kS/s about 0.1 s of
the run worker's CPU, which competed with the window for the GIL three times per run)."""

from __future__ import annotations

from collections import Counter
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

from app.io.vocabulary import RunStatus
from app.procedure import preflight, procedure, record_run
from app.procedure.options import RunOptions
from app.procedure.service import RunService

LINES = (80.0, 160.0, 315.0)


def _stand(tmp_path: Path) -> Path:
    text = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
    path = tmp_path / "stand.toml"
    path.write_text(f"{text}\n[plan]\nfrequencies_hz = [80, 160, 315]\n", encoding="utf-8")
    return path


def _counted(monkeypatch: pytest.MonkeyPatch, counts: Counter[str], module: Any, name: str):
    real = getattr(module, name)

    def counted(*args: Any, **kwargs: Any) -> Any:
        counts[f"{module.__name__.rsplit('.', 1)[-1]}.{name}"] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)


@pytest.fixture
def counts(monkeypatch: pytest.MonkeyPatch) -> Counter[str]:
    found: Counter[str] = Counter()
    _counted(monkeypatch, found, procedure, "check_preflight")
    _counted(monkeypatch, found, preflight, "motion_peaks")  # every synthesis of the motion
    _counted(monkeypatch, found, record_run, "fade_in_for")
    _counted(monkeypatch, found, record_run, "check_drive")
    return found


def test_a_run_started_as_the_window_starts_it_computes_its_preflight_once(
    tmp_path: Path, counts: Counter[str]
) -> None:
    """The GUI's path: the service's `start` (prepare: the preflight, before the folder), then
    `run()` on the worker; cold (identification burst, then the level burst)."""
    stand = _stand(tmp_path)
    service = RunService(stand)
    prepared = service.prepare(RunOptions(stand_file=stand, out=tmp_path / "runs"))
    run, opened = service.start(prepared)
    try:
        finished = run.run()
    finally:
        opened.close()
    assert finished.status == RunStatus.COMPLETE, finished.abort_reason
    assert counts["procedure.check_preflight"] == 1
    assert counts["record_run.fade_in_for"] == 0  # the preflight's fade-in is used
    assert counts["record_run.check_drive"] >= 1  # each drive is still checked before it plays
    # one synthesis for the preflight (the fade-in's judge is the report's peaks), one per
    # drive checked; none repeated
    assert counts["preflight.motion_peaks"] == 1 + counts["record_run.check_drive"]


def test_a_run_from_the_command_line_computes_its_preflight_once(
    tmp_path: Path, counts: Counter[str]
) -> None:
    """The CLI's path (`execute`: prepare, then `run()`), warm: the stored response's check
    burst, then the level."""
    stand = _stand(tmp_path)
    service = RunService(stand)
    options = RunOptions(stand_file=stand, out=tmp_path / "runs")
    assert service.run(service.prepare(options)).record.status == RunStatus.COMPLETE  # cold
    counts.clear()
    outcome = service.run(service.prepare(options))  # warm: the stored response checked first
    assert outcome.record.status == RunStatus.COMPLETE, outcome.record.abort_reason
    assert counts["procedure.check_preflight"] == 1
    assert counts["record_run.fade_in_for"] == 0
    assert counts["record_run.check_drive"] >= 2  # the check burst and the level burst
    assert counts["preflight.motion_peaks"] == 1 + counts["record_run.check_drive"]


def test_a_refused_preflight_is_refused_at_every_ask_without_computing_it_again(
    tmp_path: Path, counts: Counter[str]
) -> None:
    """The memoised report still refuses: the procedure's `preflight()` raises each time it
    is asked (prepare, then a caller that runs anyway), from one computation."""
    from app.procedure import Procedure, RunSettings
    from app.procedure.errors import PreflightError
    from app.procedure.planning import PlanRequest, build_plan
    from app.stand.config import load
    from app.stand.open import open_stand

    config = load(None)
    plan = build_plan(PlanRequest(preset="piezo", frequencies_hz=LINES))
    stand = open_stand(config, dut="piezo", seed=1)
    try:
        run = Procedure(stand, plan, RunSettings(dut_nominal_mv_per_ms2=1e4))  # overloads
        for _ in range(2):
            with pytest.raises(PreflightError, match="DUT channel"):
                run.preflight()
    finally:
        stand.close()
    assert counts["procedure.check_preflight"] == 1
