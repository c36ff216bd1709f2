"""The verdict (app.procedure.verdict, issue 13 points 6 and 7): no conformity statement without
an uncertainty, each line judged with its own U against the tolerances, the mounting check, the
verdict through the results.json round trip."""

from __future__ import annotations

import dataclasses
import json
import math

from app.certificate import CertificateInfo
from app.certificate.pdf import _statements
from app.procedure.analysis import analyze
from app.procedure.phase_store import stored_phases
from app.procedure.verdict import (
    FAIL,
    INDETERMINATE,
    PASS,
    Band,
    Tolerances,
    assess,
    decide,
    mounting_warnings,
    with_verdict,
)
from dsp.calibration import (
    LineResult,
    ReferenceResult,
    Results,
    not_stated_line,
)
from dsp.conformity import decide as conformity_decide
from dsp.multisine import preset_plan
from tests.synthetic import lowpass_response, make_recording

# --- point 6: no conformity statement without U -------------------------------------------------


def test_conformity_is_not_stated_without_an_uncertainty(tmp_path):
    assert conformity_decide(1.0, 0.0, 5.0) == "not stated"
    assert conformity_decide(1.0, math.nan, 5.0) == "not stated"
    assert conformity_decide(1.0, math.inf, 5.0) == "not stated"
    assert conformity_decide(4.0, 1.0, 5.0) == "pass"  # 4 + 1 <= 5: the boundary passes
    assert decide(1.0, 0.0, 5.0) == "not stated"
    one_period = make_recording(
        preset_plan("piezo", optimiser=stored_phases), lowpass_response(), periods=1
    )
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


def test_a_peak_beside_a_line_not_stated_blames_no_mount():
    """Issue 32 point 5: the plan's 20 kHz line rose +176 % with 25 kHz beyond the reference's
    certificate; a peak not bracketed by stated lines is no mounted resonance."""
    spec = dataclasses.replace(SPEC, characteristic=())
    results = _results((0, 0, 0, 30, 10))
    assert mounting_warnings(results)  # bracketed by stated lines: the mount is suspect
    lines = list(results.lines)
    lines[4] = not_stated_line(lines[4], "outside the reference's calibrated range")
    unbracketed = dataclasses.replace(results, lines=tuple(lines))
    assert mounting_warnings(unbracketed) == []
    verdict, reasons, _ = assess(unbracketed, spec)
    assert not any("mounting" in r for r in reasons)
    assert verdict == INDETERMINATE and any("not stated at 2500 Hz" in r for r in reasons)
