"""Issue 13, points 1, 2, 6, 7 and 8: CSV skew, re-analysis options, conformity without U,
the overall verdict with the mounting check, and the truth in every simulated recording."""

from __future__ import annotations

import dataclasses
import json
import math

import h5py
import numpy as np
import pytest

from app.certificate import CertificateError, CertificateInfo, build
from app.certificate.pdf import _charts, _line_table, _statements
from app.cli import main
from app.io.csv import read_csv
from app.io.hdf5 import RecordingError, write_recording
from app.procedure.analysis import analyze, read_for_analysis, reanalysis
from app.procedure.verdict import (
    FAIL,
    INDETERMINATE,
    PASS,
    Band,
    Tolerances,
    assess,
    decide,
    with_verdict,
)
from dsp.calibration import (
    LineResult,
    ReferenceChain,
    ReferenceResult,
    Results,
)
from dsp.conformity import decide as conformity_decide
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
    plan = preset_plan("piezo")
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
    assert {row[6] for row in cells[1:]} == {"n/s"} and {row[7] for row in cells[1:]} == {"n/s"}
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
        read_csv(path, preset_plan("piezo"), ReferenceChain.flat(1.0, skew_s=None), Budget(()))


# --- point 2: options on an HDF5 re-analysis ---------------------------------------------------


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """An 8-period HDF5 recording of a known low-pass DUT."""
    rec = make_recording(
        preset_plan("piezo"), lowpass_response(), periods=8, dut_noise_v=2e-4, seed=3
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


# --- point 6: no conformity statement without U -------------------------------------------------


def test_conformity_is_not_stated_without_an_uncertainty(tmp_path):
    assert conformity_decide(1.0, 0.0, 5.0) == "not stated"
    assert conformity_decide(1.0, math.nan, 5.0) == "not stated"
    assert conformity_decide(1.0, math.inf, 5.0) == "not stated"
    assert conformity_decide(4.0, 1.0, 5.0) == "pass"  # 4 + 1 <= 5: the boundary passes
    assert decide(1.0, 0.0, 5.0) == "not stated"
    one_period = make_recording(preset_plan("piezo"), lowpass_response(), periods=1)
    results = analyze(one_period, tolerance_percent=5.0).results  # one period: U undefined
    assert {ln.iso_verdict for ln in results.lines} == {"not stated"}
    assert {ln.tolerance_verdict for ln in results.lines} == {"not stated"}
    assert results.verdict == INDETERMINATE
    paragraphs = _statements(results, CertificateInfo(), "95.45 %")
    text = " ".join(getattr(p, "text", "") for p in paragraphs)
    assert "conformity not stated" in text and "conforms" not in text.replace("not stated", "")


# --- point 7: the verdict --------------------------------------------------------------------

FREQS = (10.0, 80.0, 160.0, 1000.0, 2500.0)


def _results(
    deviation_percent=(0.0,) * 5,
    u_percent=(1.0,) * 5,
    *,
    reference_mv=10.0,
    phase_deg=(0.0,) * 5,
    u_phase_deg=(0.5,) * 5,
    coherence=(1.0,) * 5,
    snr_db=(80.0,) * 5,
) -> Results:
    """Results built by hand: 5 lines, the reference at 160 Hz (index 2)."""
    lines = []
    for k, f in enumerate(FREQS):
        s = reference_mv * (1 + deviation_percent[k] / 100)
        u_rel = u_percent[k] / 100
        values = {
            "nominal_frequency_hz": f,
            "frequency_hz": f,
            "sensitivity_mv_per_ms2": s,
            "sensitivity_db": 20 * math.log10(s),
            "deviation_percent": deviation_percent[k],
            "deviation_db": 0.0,
            "phase_deg": phase_deg[k],
            "relative_type_a": 0.0,
            "relative_type_b": u_rel / 2,
            "relative_standard_uncertainty": u_rel / 2,
            "relative_expanded_uncertainty": u_rel,
            "expanded_uncertainty_mv_per_ms2": s * u_rel,
            "coverage_factor": 2.0,
            "effective_dof": math.inf,
            "phase_expanded_uncertainty_deg": u_phase_deg[k],
            "phase_coverage_factor": 2.0,
            "coherence": coherence[k],
            "reference_snr_db": snr_db[k],
            "dut_snr_db": snr_db[k],
            "dut_distortion_percent": 0.0,
            "iso_limit": 0.02,
            "iso_verdict": "within",
        }
        lines.append(LineResult(**values))
    r = lines[2]
    reference = ReferenceResult(
        frequency_hz=160.0,
        actual_frequency_hz=160.0,
        sensitivity_mv_per_ms2=r.sensitivity_mv_per_ms2,
        sensitivity_db=r.sensitivity_db,
        expanded_uncertainty_mv_per_ms2=r.expanded_uncertainty_mv_per_ms2,
        relative_expanded_uncertainty=r.relative_expanded_uncertainty,
        coverage_factor=2.0,
        coverage_probability=0.9545,
        phase_deg=r.phase_deg,
        phase_expanded_uncertainty_deg=r.phase_expanded_uncertainty_deg,
    )
    return Results("periodic", 8, 6000.0, 12000, 0.9545, "gum", reference, tuple(lines))


SPEC = Tolerances(
    nominal_sensitivity_mv_per_ms2=10.0,
    sensitivity_percent=5.0,
    characteristic=(Band(0.0, 5000.0, 5.0),),
    phase=(Band(0.0, 5000.0, 5.0),),
)


def test_clean_results_pass():
    # 3.9 % with U(dev) = (1 + 0.039) * 1 % = 1.039 %: 4.939 % <= 5 %, passes
    verdict, reasons, mounting = assess(_results((1, 1, 0, -1, 3.9)), SPEC)
    assert verdict == PASS and not mounting
    assert any(r.startswith("amplitude characteristic: pass at all 4") for r in reasons)
    assert any(r.startswith("phase: pass at all 5") for r in reasons)


def test_the_deviation_is_judged_with_its_own_uncertainty():
    # dsp.characteristic: U(dev) = (1 + dev) * U_rel(S); at 4 % with U_rel 1 %, U(dev) is
    # 1.04 % and 4 + 1.04 > 5: inconclusive (with U_rel itself it would be 4 + 1 = 5: pass)
    verdict, reasons, _ = assess(_results((1, 1, 0, -1, 4)), SPEC)
    assert verdict == INDETERMINATE and any("inconclusive at 2500 Hz" in r for r in reasons)


def test_out_of_tolerance_fails():
    verdict, reasons, _ = assess(_results((1, 1, 0, -1, 6.5)), SPEC)  # 6.5 - 1 > 5
    assert verdict == FAIL and any("fail at 2500 Hz" in r for r in reasons)
    low = assess(_results(reference_mv=9.3), SPEC)  # -7 % from nominal 10: 7 - 1 > 5
    assert low[0] == FAIL and "sensitivity at 160 Hz: fail" in low[1][0]
    phase = assess(_results(phase_deg=(0, 0, 0, 0, -6)), SPEC)  # |-6| - 0.5 > 5
    assert phase[0] == FAIL and any("phase: fail at 2500 Hz" in r for r in phase[1])


def test_straddling_the_tolerance_is_indeterminate():
    verdict, reasons, _ = assess(_results((1, 1, 0, -1, 4.5)), SPEC)  # 4.5 <= 5 < 4.5 + 1
    assert verdict == INDETERMINATE and any("inconclusive at 2500 Hz" in r for r in reasons)
    outside = assess(_results((1, 1, 0, -1, 5.5)), SPEC)[0]  # 5.5 > 5 but 5.5 - 1 <= 5
    assert outside == INDETERMINATE
    no_u = assess(_results(u_percent=(1, 1, 1, 1, 0)), SPEC)
    assert no_u[0] == INDETERMINATE and any("not stated at 2500 Hz" in r for r in no_u[1])
    assert assess(_results(), Tolerances())[0] == INDETERMINATE  # nothing to judge against
    assert assess(_results(), SPEC, status="aborted")[0] == INDETERMINATE


def test_a_resonance_or_an_unexplained_coherence_drop_is_a_mounting_warning():
    # a peak of +30 % at 1000 Hz, inside the range; no characteristic tolerance, so only the
    # mounting check stands between this and PASS
    spec = dataclasses.replace(SPEC, characteristic=())
    results = with_verdict(_results((0, 0, 0, 30, 10)), spec)
    assert results.verdict == INDETERMINATE
    assert any(w.startswith("mounting: a resonance near 1000 Hz") for w in results.warnings)
    assert assess(_results((0, 0, 0, 20, 10)), spec)[0] == PASS  # +20 %: not a resonance
    assert assess(_results((0, 0, 0, 10, 30)), spec)[0] == PASS  # rising to the top line
    drop = assess(_results(coherence=(1, 1, 1, 0.95, 1)), SPEC)
    assert drop[0] == INDETERMINATE and "mounting: coherence 0.950 at 1000 Hz" in drop[2][0]
    noisy = assess(_results(coherence=(1, 1, 1, 0.95, 1), snr_db=(80, 80, 80, 25, 80)), SPEC)
    assert noisy[0] == PASS and not noisy[2]  # noise explains it


def test_verdict_survives_the_round_trip():
    results = with_verdict(_results(), SPEC)
    again = Results.from_dict(json.loads(json.dumps(results.to_dict())))
    assert again.verdict == PASS and again.verdict_reasons == results.verdict_reasons


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
    # issue 25 point 2 (a deliberate change): `simulate` records no drive-off periods, so the
    # hum at the lines on mains harmonics is not separable and blocks PASS; every check passes
    assert results.verdict == "INDETERMINATE"
    assert all(r.startswith("blocks PASS (hum not separable)") for r in results.verdict_reasons[3:])
    assert all(": pass" in r for r in results.verdict_reasons[:3])
