"""`accelcal analyze` (issue 13, points 1, 2 and 8): CSV skew, re-analysis options, and the truth
in every simulated recording with its verdict (the verdict itself: tests/app/procedure/
test_verdict.py)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from app.certificate import CertificateError, CertificateInfo, build
from app.certificate.pdf import _charts, _line_table
from app.cli import main
from app.io.csv import read_csv
from app.io.hdf5 import RecordingError, write_recording
from app.procedure.analysis import analyze, read_for_analysis, reanalysis
from app.procedure.phase_store import stored_phases
from app.procedure.verdict import (
    PASS,
)
from dsp.calibration import (
    ReferenceChain,
    Results,
)
from dsp.multisine import preset_plan
from dsp.uncertainty import Budget
from tests.synthetic import lowpass_response, make_recording
from tests.within_u import assert_consistent_with_u

SKEW_S = 2e-6
# hand: the skew's phase at the top line, 360 deg * 2500 Hz * 2 us = 1.8 deg
SKEW_PHASE_AT_2500_DEG = 1.8


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _wrap(deg: np.ndarray) -> np.ndarray:
    return (np.asarray(deg) + 180.0) % 360.0 - 180.0


# --- point 1: channel skew from CSV -----------------------------------------------------------


def _skewed_csv(tmp_path, skew_s: float, header: str | None = None):
    """A CSV of a low-pass DUT sampled `skew_s` after the reference (fractional delay made in
    the frequency domain by tests.synthetic), with a little noise so that U > 0."""
    plan = preset_plan("piezo", optimiser=stored_phases)
    rec = make_recording(
        plan,
        lowpass_response(),
        periods=8,
        reference_noise_v=5e-6,
        dut_noise_v=5e-5,
        skew_s=skew_s,
        seed=7,
    )
    path = tmp_path / f"skew{skew_s:+g}.csv"
    lines = ([header] if header else []) + ["reference_v,dut_v"]
    lines += [f"{float(a)!r},{float(b)!r}" for a, b in zip(rec.reference_v, rec.dut_v, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    budget = tmp_path / "budget.toml"  # the DAQ's channel phase match: +-0.1 deg
    budget.write_text(
        '[[component]]\nname = "phase match"\nvalue = 0.1\ndistribution = "rectangular"\n'
        'quantity = "phase"\n'
    )
    return path, plan


CSV_OPTIONS = ("--preset", "piezo", "--reference-sensitivity", "1", "--json")


def run_csv(capsys, path, *options: str) -> tuple[int, str, str]:
    budget = str(path.parent / "budget.toml")
    return run(capsys, "analyze", str(path), *CSV_OPTIONS, "--budget", budget, *options)


def _phase_errors(data: dict, plan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """|phase error| (deg), U (deg) and k per line."""
    truth = np.degrees(np.angle(lowpass_response()(plan.frequencies_hz)))
    phase = np.array([ln["phase_deg"] for ln in data["lines"]])
    u = np.array([ln["phase_expanded_uncertainty_deg"] for ln in data["lines"]])
    k = np.array([ln["phase_coverage_factor"] for ln in data["lines"]])
    return np.abs(_wrap(phase - truth)), u, k


@pytest.mark.parametrize("skew_s", [SKEW_S, -SKEW_S])
@pytest.mark.parametrize("form", ["separate", "equals", "header"])
def test_csv_skew_corrects_the_phase_in_both_directions(capsys, tmp_path, skew_s, form):
    header = f"# skew_s = {skew_s!r}" if form == "header" else None
    path, plan = _skewed_csv(tmp_path, skew_s, header)
    option = {
        "separate": ["--skew", repr(skew_s)],
        "equals": [f"--skew={skew_s!r}"],
        "header": [],
    }[form]
    code, out, err = run_csv(capsys, path, *option)
    assert code == 0, err
    data = json.loads(out)
    assert data["phase_corrected_for_skew"] is True
    error, u, k = _phase_errors(data, plan)
    assert np.all(u > 0)
    assert_consistent_with_u(("phase", error, u, k))  # tests/within_u.py
    assert u[-1] < SKEW_PHASE_AT_2500_DEG / 2  # so a wrong sign (2 x 1.8 deg off) would show
    assert error[-1] < 0.05  # hand: corrected to well within the 0.1 deg phase match


def test_csv_without_skew_is_flagged_and_the_certificate_states_no_phase(capsys, tmp_path):
    path, plan = _skewed_csv(tmp_path, SKEW_S)
    code, out, err = run_csv(capsys, path)
    assert code == 0, err
    data = json.loads(out)
    assert data["phase_corrected_for_skew"] is False
    assert any("not corrected for skew" in w for w in data["warnings"])
    error, u, k = _phase_errors(data, plan)
    off = np.array([error[-1] - SKEW_PHASE_AT_2500_DEG])  # off by the skew, and by no more
    assert_consistent_with_u(("phase at 2500 Hz", off, u[-1:], k[-1:]))  # tests/within_u.py
    assert error[-1] > u[-1]  # the uncorrected phase is off by more than its U
    code, out, _ = run(capsys, *(a for a in ("analyze", str(path), *CSV_OPTIONS) if a != "--json"))
    assert code == 0 and "not corrected for skew" in out and " n/c " in out
    # the certificate's pieces: no phase values, no phase chart
    results = Results.from_dict(data)
    cells = _line_table(results)[1]._cellvalues
    assert {row[7] for row in cells[1:]} == {"n/s"} and {row[8] for row in cells[1:]} == {"n/s"}
    flow = _charts(results)[0]._content
    texts = [getattr(item, "text", "") for item in flow]
    assert any("Phase-frequency characteristic: not stated" in t for t in texts)
    assert sum(type(item).__name__ == "Drawing" for item in flow) == 1  # amplitude chart only


def test_skew_option_and_header_must_agree(capsys, tmp_path):
    path, _ = _skewed_csv(tmp_path, SKEW_S, f"# skew_s = {SKEW_S!r}")
    code, _, err = run_csv(capsys, path, "--skew", "-2e-06")
    assert code == 2 and "disagrees" in err and "skew_s" in err
    path.write_text("# skew_s = fast\n1,2\n")
    with pytest.raises(RecordingError, match="line 1: skew_s 'fast'"):
        read_csv(
            path,
            preset_plan("piezo", optimiser=stored_phases),
            ReferenceChain.flat(1.0, skew_s=None),
            Budget(()),
        )


# --- point 2: options on an HDF5 re-analysis ---------------------------------------------------


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """An 8-period HDF5 recording of a known low-pass DUT."""
    rec = make_recording(
        preset_plan("piezo", optimiser=stored_phases),
        lowpass_response(),
        periods=8,
        dut_noise_v=2e-4,
        seed=3,
    )
    path = tmp_path_factory.mktemp("h5") / "recording.h5"
    write_recording(path, rec)
    return path


def test_reference_frequency_is_applied_or_refused(capsys, stored):
    code, out, err = run(capsys, "analyze", str(stored), "--reference-frequency", "80", "--json")
    assert code == 0, err
    data = json.loads(out)
    assert data["reference"]["frequency_hz"] == 80.0 and data["reanalysis"] == {
        "reference_frequency_hz": 80.0
    }
    by_f = {ln["nominal_frequency_hz"]: ln for ln in data["lines"]}
    s80 = by_f[80.0]["sensitivity_mv_per_ms2"]
    assert by_f[80.0]["deviation_percent"] == 0.0
    expected = 100 * (by_f[2500.0]["sensitivity_mv_per_ms2"] / s80 - 1)
    assert by_f[2500.0]["deviation_percent"] == pytest.approx(expected, rel=1e-12)
    code, _, err = run(capsys, "analyze", str(stored), "--reference-frequency", "85")
    assert code == 2 and "--reference-frequency: 85 Hz is not a line" in err


def test_settle_periods_drop_leading_periods_or_are_refused(capsys, stored):
    code, out, err = run(capsys, "analyze", str(stored), "--settle-periods", "3", "--json")
    assert code == 0, err
    assert json.loads(out)["periods"] == 5  # 8 - 3
    code, _, err = run(capsys, "analyze", str(stored), "--settle-periods", "7")
    assert code == 2 and "--settle-periods" in err and "fewer than 2" in err


def test_mains_is_applied_to_the_plan(capsys, stored):
    recording = read_for_analysis(stored)
    assert any("mains harmonic (50 Hz)" in w for w in recording.plan.warnings)
    sixty = reanalysis(recording, mains_frequency_hz=60.0)
    assert sixty.plan.mains_frequency_hz == 60.0
    assert not any("mains harmonic" in w for w in sixty.plan.warnings)  # no line on 60 n Hz
    code, out, err = run(capsys, "analyze", str(stored), "--mains", "60", "--json")
    assert code == 0, err
    assert json.loads(out)["reanalysis"] == {"mains_frequency_hz": 60.0}


def test_level_is_refused_on_a_recording(capsys, stored):
    code, _, err = run(capsys, "analyze", str(stored), "--level", "3")
    assert code == 2 and "--level: not allowed with an HDF5 recording" in err


# --- points 7 and 8 on the simulated stand ------------------------------------------------------


@pytest.fixture(scope="module")
def sim_runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs")
    records = {}
    for dut in ("piezo", "loose"):
        code = main(["run", "--sim", "--dut", dut, "--periods", "4", "--out", str(out), "--json"])
        assert code in (0, 3)
        ids = sorted(p.name for p in out.iterdir() if p.name.endswith(dut) or f"-{dut}-" in p.name)
        records[dut] = out / ids[-1]
    return records


def test_clean_run_passes_with_the_truth_in_its_recording(capsys, sim_runs):
    folder = sim_runs["piezo"]
    record = json.loads((folder / "results.json").read_text())
    assert record["verdict"] == PASS and record["results"]["verdict"] == PASS
    with h5py.File(folder / "recording.h5", "r") as f:
        truth = {k: f["truth"][k][()] for k in ("frequency_hz", "sensitivity_mv_per_ms2")}
        truth_phase = f["truth"]["phase_deg"][()]
        assert f["truth"].attrs["dut"] == "piezo"
    lines = record["results"]["lines"]
    np.testing.assert_array_equal(truth["frequency_hz"], [ln["frequency_hz"] for ln in lines])
    s = np.array([ln["sensitivity_mv_per_ms2"] for ln in lines])
    u = np.array([ln["expanded_uncertainty_mv_per_ms2"] for ln in lines])
    phase = np.array([ln["phase_deg"] for ln in lines])
    u_phase = np.array([ln["phase_expanded_uncertainty_deg"] for ln in lines])
    k, k_phase = (
        np.array([ln[key] for ln in lines]) for key in ("coverage_factor", "phase_coverage_factor")
    )
    assert_consistent_with_u(  # tests/within_u.py
        ("magnitude", s - truth["sensitivity_mv_per_ms2"], u, k),
        ("phase", _wrap(phase - truth_phase), u_phase, k_phase),
    )
    code, out, _ = run(capsys, "show", str(folder))
    assert code == 0 and "VERDICT: PASS" in out
    code, out, _ = run(capsys, "show", str(folder), "--json")
    assert json.loads(out)["results"]["verdict"] == PASS


def test_loose_mount_is_warned_and_never_passes(capsys, sim_runs, tmp_path):
    folder = sim_runs["loose"]
    record = json.loads((folder / "results.json").read_text())
    assert record["verdict"] != PASS
    assert any(w.startswith("mounting: a resonance near") for w in record["results"]["warnings"])
    code, out, _ = run(capsys, "analyze", str(folder), "--json")  # re-analysis agrees
    assert code == 0 and json.loads(out)["verdict"] == record["verdict"]
    info = CertificateInfo(
        customer="ACME Ltd",
        customer_address="1 Test Street, 00-001 Testtown",
        authorised_by="J. Smith",
        temperature_c=23.0,
        mounting="stud",
        dut_serial="SN-1",
    )
    # issue 25 point 2 (a deliberate change): a mounting warning blocks the certificate
    with pytest.raises(CertificateError, match=r"no certificate: .*mounting: a resonance near"):
        build(folder, info, tmp_path / "c.pdf")
    assert not (tmp_path / "c.pdf").exists()


def test_simulate_recording_carries_the_truth_and_a_verdict(tmp_path):
    from app.procedure.simulate import simulate

    run_ = simulate(tmp_path / "rec.h5", dut="piezo", periods=4, seed=2)
    recording = read_for_analysis(run_.path)
    assert recording.truth is not None and recording.truth.attrs["dut"] == "piezo"
    results = analyze(recording).results
    # issue 25 point 2: `simulate` records no drive-off periods, so hum at a line on a mains
    # harmonic would not be separable and would block PASS. Issue 32 (a deliberate change):
    # the plan moves those lines one bin, the hum falls on free bins and leaks onto no line,
    # so nothing is inseparable and every check passes
    on_mains = [ln.frequency_hz for ln in results.lines if ln.frequency_hz in (50, 100, 200, 250)]
    assert on_mains == []
    assert not any("not separable" in w for w in results.warnings)
    assert results.verdict == "PASS", results.verdict_reasons
    assert all(": pass" in r for r in results.verdict_reasons[:3])
