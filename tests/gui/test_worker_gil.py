"""The run worker hands the GIL over sooner (issue 34 point 6): from its start the switch
interval is GIL_SWITCH_S, never lengthened, so a window callback waits at most about that long
for a computing worker (CPython's 5 ms made a frame of ten callbacks wait up to 50 ms); and it
keeps the run's phase for the GUI bench's stall report."""

from __future__ import annotations

import sys
from collections.abc import Iterator

import pytest

from app.gui import worker
from app.gui.worker import RunWorker
from app.procedure import State, StateChanged


@pytest.fixture
def interval() -> Iterator[None]:
    before = sys.getswitchinterval()
    yield
    sys.setswitchinterval(before)


def test_the_switch_interval_is_shortened_and_never_lengthened(interval: None) -> None:
    assert worker.GIL_SWITCH_S < 0.005  # shorter than CPython's default
    sys.setswitchinterval(0.005)
    assert worker.hand_gil_over_sooner() == pytest.approx(worker.GIL_SWITCH_S)
    assert sys.getswitchinterval() == pytest.approx(worker.GIL_SWITCH_S)
    sys.setswitchinterval(0.0001)  # a shorter one set by the caller stays
    assert worker.hand_gil_over_sooner() == pytest.approx(0.0001)


def test_a_run_worker_shortens_it_as_it_starts(interval: None) -> None:
    sys.setswitchinterval(0.005)

    def refused() -> tuple[object, object]:
        raise ValueError("no stand here")

    run = RunWorker.opening(refused)  # type: ignore[arg-type]
    run.start()
    assert run.join(10.0)
    assert isinstance(run.refusal, ValueError)
    assert sys.getswitchinterval() == pytest.approx(worker.GIL_SWITCH_S)


def test_the_worker_keeps_the_runs_phase() -> None:
    run = RunWorker(None, None)
    assert run.state is None
    run._on_event(StateChanged(State.BACKGROUND, "drive at 0 V"))
    assert run.state is State.BACKGROUND
    run._on_event(StateChanged(State.IDENTIFYING))
    assert run.state is State.IDENTIFYING
    assert [type(e) for e in run.drain()] == [StateChanged, StateChanged]  # still queued
