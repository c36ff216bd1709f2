"""Issue 33 point 6: every sample rate and period the options accept is one this machine can do,
or refused before anything is allocated or moves (exit 2, naming the memory or the recording it
would take). Before: `run --sample-rate 3e6` ended in an internal error (exit 3), `1e7` in a
MemoryError (exit 1), `plan --period 16777216 --sample-rate 1e7` took 131 s and 4.3 GB."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.procedure import capacity
from dsp import crestfactor
from dsp.crestfactor import PEAK_GRID_MAX, peak_grid_samples


@pytest.fixture()
def one_gigabyte(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A machine with 1 GB available (its /proc/meminfo)."""
    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal: 4000000 kB\nMemAvailable: 1000000 kB\n", encoding="ascii")
    monkeypatch.setattr(capacity, "MEMINFO", meminfo)


@pytest.mark.parametrize("rate", ["3e6", "1e7"])
def test_a_run_at_a_rate_the_recording_cannot_hold_is_refused_before_anything(
    rate: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    started = time.process_time()
    code = main(["run", "--sim", "--sample-rate", rate, "--out", str(tmp_path / "runs")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "more than a recording may hold" in err and "--sample-rate" in err
    assert "Traceback" not in err and not (tmp_path / "runs").exists()
    assert time.process_time() - started < 5.0  # refused before the phases are optimised


def test_a_plan_the_machine_has_not_the_memory_for_is_refused_naming_it(
    one_gigabyte: None, capsys: pytest.CaptureFixture[str]
) -> None:
    started = time.process_time()
    code = main(["plan", "--period", "16777216", "--sample-rate", "1e7"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "1.9 GB of memory" in err and "this machine can give it 512 MB" in err
    assert "16777216 samples at 1e+07 Hz" in err
    assert time.process_time() - started < 5.0


def test_a_run_of_more_periods_than_a_recording_holds_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The preset plan is small; 10000 periods of it are not (120 million samples)."""
    code = main(["run", "--sim", "--periods", "10000", "--out", str(tmp_path / "runs")])
    err = capsys.readouterr().err
    assert code == 2 and "a run of 10000 periods of 12000 samples" in err, err
    assert not (tmp_path / "runs").exists()


def test_the_estimate_bounds_what_was_measured() -> None:
    """A run at 409.6 kS/s (N = 819200, 8 periods) peaked at 311 MB: the estimate is above it;
    the plan of 2^24 samples took 4.3 GB before its peaks were taken on a bounded grid."""
    assert capacity.plan_cost(819200, 8).memory_bytes > 311e6
    assert capacity.plan_cost(2**24, top_bin=4194).memory_bytes < 2.5e9
    assert capacity.plan_cost(12000).memory_bytes < 300e6  # the presets: no refusal anywhere


def test_the_phase_optimisation_is_bounded_by_the_period() -> None:
    """The work (evaluations x N) stays within MAX_WORK_SAMPLES; the presets keep their cap."""
    assert crestfactor.evaluation_cap(12000) == crestfactor.DEFAULT_MAX_EVALUATIONS
    assert crestfactor.evaluation_cap(24000) == crestfactor.DEFAULT_MAX_EVALUATIONS
    for n in (204800, 2_000_000, 2**24):
        assert crestfactor.evaluation_cap(n) * n <= crestfactor.MAX_WORK_SAMPLES
    assert crestfactor.evaluation_cap(2**25) >= 2


def test_the_peak_grid_is_bounded_and_still_sees_the_peaks() -> None:
    """Up to 2^23 points the grid is 8x the period as before; past it the same waveform on
    PEAK_GRID_MAX points gives the same peak within 1e-6 (lines far below the grid's rate)."""
    assert peak_grid_samples(12000, [5000]) == 96000
    assert peak_grid_samples(2**24, [4194]) == PEAK_GRID_MAX
    assert peak_grid_samples(2**24, [2**22]) == 2**26  # 16 points a period of the top line
    bins, amplitudes, phases = np.array([3, 40, 700]), np.ones(3), np.array([0.1, 1.0, 2.0])
    fine = crestfactor.synthesize(bins, amplitudes, phases, 2**16)
    coarse = crestfactor.synthesize(bins, amplitudes, phases, 16 * 700)
    assert np.max(np.abs(coarse)) == pytest.approx(np.max(np.abs(fine)), rel=1e-3)
