"""Issue 34 point 2: shorter fades, the preflight's peaks covering them, and the stored
response's check as a short burst before the level (both estimators)."""

import json

import numpy as np
import pytest

from app.io.vocabulary import RunStatus
from app.procedure import Procedure, RunSettings
from app.procedure.phase_store import stored_phases
from app.procedure.preflight import check_preflight, fade_in_for, motion_peaks
from app.stand.config import load
from app.stand.open import open_stand
from app.stand.response import ResponseStore
from dsp.multisine import preset_plan

CONFIG = load()


def _target(plan, scale=1.0):
    return scale * plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))


def test_a_level_whose_short_fade_in_would_pass_the_stroke_gets_a_longer_one():
    """The seed plan scaled to 7.8 mm p-p of steady orbit on the 8 mm exciter: a one-cycle
    fade-in's offset (1.6 mm at 5 m/s^2, free mass) would take it past the stroke, so the
    preflight refuses that fade-in, naming the displacement, and the LPM's fade-in chosen for
    the level (`fade_in_for`) is longer, with which the level passes; with no fade counted it
    would have passed whatever the fade."""
    plan = preset_plan("piezo", optimiser=stored_phases)
    steady = plan.predicted_peaks().displacement_peak_to_peak_m
    scale = 7.8e-3 / steady
    assert steady * scale < CONFIG.limits.displacement_peak_to_peak_m
    one_cycle = check_preflight(plan, CONFIG, None, level_scale=scale, fade_in_s=0.1)
    assert any("displacement" in p and "8 mm" in p for p in one_cycle.problems), one_cycle
    chosen = fade_in_for(plan, _target(plan, scale), CONFIG.limits)
    assert chosen > 0.1
    assert check_preflight(plan, CONFIG, None, level_scale=scale).ok
    assert fade_in_for(plan, _target(plan), CONFIG.limits) == pytest.approx(0.1)  # at 5 m/s^2
    faded = motion_peaks(plan, _target(plan))
    assert faded.displacement_peak_to_peak_m > steady + 1e-3  # the fades count
    assert faded.velocity_m_per_s > plan.predicted_peaks().velocity_m_per_s


def test_the_long_stroke_plan_keeps_its_stroke_with_the_shorter_fades():
    """The README's 0.4-8 Hz plan (1.5 m/s^2, displacement below 3 Hz) on the 150 mm exciter:
    fades of 2.46 s in and 3.69 s out add under 10 mm to its 54 mm p-p orbit."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "bench"))
    from excitation_time import low_plan

    from app.procedure.run import with_exciter

    plan = low_plan()
    config = with_exciter(CONFIG, "long-stroke")
    report = check_preflight(plan, config, None)
    assert report.ok, report.problems
    steady = plan.predicted_peaks().displacement_peak_to_peak_m
    assert steady < report.peaks.displacement_peak_to_peak_m < steady + 10e-3
    assert report.peaks.displacement_peak_to_peak_m < config.limits.displacement_peak_to_peak_m


def _recorded_run(store, monkeypatch, estimator):
    """One run of the seed plan; the table's displacement as the simulator moved it."""
    import sim.stand

    seen: list[np.ndarray] = []
    process = sim.stand.MultiZoh.process

    def recording(self, u):
        out = process(self, u)
        seen.append(out["displacement"].copy())
        return out

    monkeypatch.setattr(sim.stand.MultiZoh, "process", recording)
    plan = preset_plan("piezo", optimiser=stored_phases)
    stand = open_stand(CONFIG, dut="piezo", seed=5, systematic=False)
    settings = RunSettings(
        estimator=estimator,
        periods=1 if estimator == "lpm" else 3,
        target_type_a=0.002,
        dut_mass_g=10.0,
    )
    try:
        finished = Procedure(stand, plan, settings, response_store=store).run()
    finally:
        stand.close()
    monkeypatch.setattr(sim.stand.MultiZoh, "process", process)
    return finished, np.concatenate(seen), plan, stand


def test_the_simulated_tables_motion_stays_within_the_predicted_peaks(tmp_path, monkeypatch):
    """Cold and warm lpm runs (identification, check and level bursts, their fades): the
    displacement the simulator moved the table through stays within the preflight's
    prediction with the fades (free mass during a fade: conservative on this exciter, whose
    orbit follows the drive), and every run ends at exactly 0 V."""
    store = ResponseStore(tmp_path / "store")
    for _ in ("cold", "warm"):
        finished, d, plan, stand = _recorded_run(store, monkeypatch, "lpm")
        assert finished.status == RunStatus.COMPLETE, finished.abort_reason
        assert stand.daq.output.periods[-1].last_v == 0.0
        peaks = motion_peaks(plan, _target(plan))
        assert -peaks.displacement_m <= d.min() and d.max() <= peaks.displacement_m
        assert np.ptp(d) <= peaks.displacement_peak_to_peak_m


def _tamper(store, scale):
    for path in store.root.rglob("*.json"):
        data = json.loads(path.read_text())
        for e in data["entries"]:
            e["response_real"] = (np.asarray(e["response_real"]) * scale).tolist()
            e["response_imag"] = (np.asarray(e["response_imag"]) * scale).tolist()
        path.write_text(json.dumps(data))


@pytest.mark.parametrize("estimator", ["lpm", "periodic"])
def test_a_wrong_stored_response_is_caught_by_a_short_burst_before_the_level(
    tmp_path, monkeypatch, estimator
):
    """Issue 25 point 7 with issue 34's short check burst (and in the lpm's path, which had
    none: a stored response 0.3 times the stand's tripped the over-travel interlock). The
    burst plays 0.3 s at 20 % of the level inside one period; the level is refused naming the
    predicted displacement, the table never passes the stroke, the drive ends at 0 V."""
    store = ResponseStore(tmp_path / "store")
    first, _, _, _ = _recorded_run(store, monkeypatch, estimator)
    assert first.status == RunStatus.COMPLETE, first.abort_reason
    _tamper(store, 0.3)
    refused, d, _, stand = _recorded_run(store, monkeypatch, estimator)
    assert refused.status == RunStatus.ABORTED
    assert "predicted displacement" in refused.abort_reason
    assert "refused before it is played" in refused.abort_reason
    assert not stand.daq._amp_tripped
    assert np.ptp(d) < 0.5 * CONFIG.limits.displacement_peak_to_peak_m
    assert refused.record.excitation_time_s == pytest.approx(0.3, abs=0.01)
    assert stand.daq.output.periods[-1].last_v == 0.0


def test_the_check_burst_costs_0_3_s_warm_and_finds_the_stored_response_right(tmp_path):
    """Warm excitation of the seed plan at 0.2 % type A: lpm 0.3 s check + 0.1 s fade-in +
    2 s record + 0.15 s fade-out = 2.55 s; periodic 0.3 s check + 2 s crossfade + 3 periods +
    0.15 s = 8.45 s (12.4 s with issue 25's crossfade and check period at 20 %)."""
    store = ResponseStore(tmp_path / "store")
    plan = preset_plan("piezo", optimiser=stored_phases)
    for estimator, warm_s in (("lpm", 2.55), ("periodic", 8.45)):
        times = []
        for _ in ("cold", "warm"):
            stand = open_stand(CONFIG, dut="piezo", seed=5, systematic=False)
            settings = RunSettings(
                estimator=estimator,
                periods=1 if estimator == "lpm" else 3,
                target_type_a=0.002,
                dut_mass_g=10.0,
            )
            try:
                finished = Procedure(stand, plan, settings, response_store=store).run()
            finally:
                stand.close()
            assert finished.status == RunStatus.COMPLETE, finished.abort_reason
            times.append(finished.record.excitation_time_s)
        assert finished.record.stand_response["source"] == "stored"
        assert finished.record.stand_response["check_error"] < 0.05
        assert times[1] == pytest.approx(warm_s, abs=0.01), (estimator, times)
