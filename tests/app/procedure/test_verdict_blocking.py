"""Issue 25 acceptance, the integration: a stand file with no type B components gives a run
that is not PASS and no certificate (the missing Annex A components named); a line over the
ISO limit or below the coherence limit keeps a run from PASS; the certificate prints what
does not block it and the Monte Carlo interval where JCGM 101 clause 8 failed."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from app.certificate.statements import mcm_statements, printed_warnings
from app.cli import main
from app.procedure.analysis import analyze
from app.procedure.simulate import simulate
from app.procedure.verdict import with_verdict
from app.records.warnings import SEED_RULE_WARNING
from app.stand.dut import Tolerances
from dsp.calibration import compute_results

pytestmark = pytest.mark.integration


def _without_type_b(text: str) -> str:
    """The shipped simulated stand file with every [[component]], the [simulation] table and
    the skew tolerance removed: a stand that states no type B budget at all."""
    text = re.sub(r"\[\[component\]\].*?(?=\n\[)", "", text, flags=re.S)
    text = re.sub(r"^\[simulation\].*\Z", "", text, flags=re.S | re.M)
    return re.sub(r"^skew_tolerance_s.*$", "", text, flags=re.M)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory):
    """A simulated piezo recording (8 periods) at the stand's nominal values."""
    out = tmp_path_factory.mktemp("rec") / "r.h5"
    from app.io.hdf5 import read_recording

    simulate(out, dut="piezo", periods=8, seed=3, systematic=False)
    return read_recording(out)


TOLERANCES = Tolerances(
    nominal_sensitivity_mv_per_ms2=None, sensitivity_percent=None, characteristic=(), phase=()
)


def test_a_stand_without_type_b_components_is_not_pass_and_gets_no_certificate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    stand = tmp_path / "stand.toml"
    shipped = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
    stand.write_text(_without_type_b(shipped))
    assert "[[component]]" not in stand.read_text()
    out = tmp_path / "runs"
    out.mkdir()
    argv = ["run", "--stand", str(stand), "--dut", "piezo", "--dut-id", "SN-1"]
    code = main([*argv, "--periods", "4", "--tolerance", "5", "--out", str(out), "--json"])
    record = json.loads(capsys.readouterr().out)
    assert code == 0 and record["status"] == "complete"
    results = record["results"]
    assert results["verdict"] != "PASS"
    assert any(r.startswith("blocks PASS (incomplete budget)") for r in results["verdict_reasons"])
    assert "magnitude: temperature (temperature)" in results["missing_components"]
    assert len(results["missing_components"]) == 14  # every Annex A entry (dsp.annex_a)
    run = out / record["run_id"]
    pdf = tmp_path / "c.pdf"
    cert = [
        "certificate",
        str(run),
        "--customer",
        "ACME",
        "--customer-address",
        "1 Test Street, 00-001 Testtown",
        "--authorised-by",
        "J. Smith",
    ]
    cert += ["--temperature", "23", "--mounting", "stud", "--out", str(pdf)]
    assert main(cert) == 2
    err = capsys.readouterr().err
    assert "Annex A component(s)" in err and "(reference_calibration)" in err
    assert "(channel_phase_match)" in err and "Traceback" not in err
    assert not pdf.exists()


def test_a_line_over_the_iso_limit_keeps_the_run_from_pass(recording) -> None:
    results = analyze(recording, tolerances=TOLERANCES).results
    clean = with_verdict(dataclasses.replace(results, warnings=()), _tolerance_5())
    assert clean.verdict == "PASS", clean.verdict_reasons
    lines = list(clean.lines)
    lines[3] = dataclasses.replace(lines[3], iso_verdict="over")
    over = with_verdict(dataclasses.replace(clean, lines=tuple(lines)), _tolerance_5())
    assert over.verdict == "INDETERMINATE"
    assert any("(ISO over)" in r and "line 20 Hz" in r for r in over.verdict_reasons)
    assert any("over the ISO 16063-21 limit" in w for w in over.warnings)


def test_a_line_below_the_coherence_limit_keeps_the_run_from_pass(recording) -> None:
    analysis = analyze(recording, tolerances=TOLERANCES)
    estimate = analysis.estimate
    coherence = np.array(estimate.coherence, dtype=float)
    coherence[5] = 0.98  # under dsp.calibration.LOW_COHERENCE (0.99)
    low = dataclasses.replace(estimate, coherence=coherence)
    results = compute_results(
        low,
        recording.plan,
        recording.chain,
        _full_budget(recording),
        tolerance_percent=5.0,
        cmc=_stand_cmc(),
    )
    judged = with_verdict(results, _tolerance_5())
    assert judged.verdict == "INDETERMINATE"
    assert any("(low coherence)" in r for r in judged.verdict_reasons)
    coherence[5] = 0.995
    ok = compute_results(
        dataclasses.replace(estimate, coherence=coherence),
        recording.plan,
        recording.chain,
        _full_budget(recording),
        tolerance_percent=5.0,
        cmc=_stand_cmc(),
    )
    assert with_verdict(ok, _tolerance_5()).verdict == "PASS"


def test_the_seed_rule_blocks_and_says_why_it_is_not_gum(recording) -> None:
    results = analyze(recording, rule="seed", tolerance_percent=5.0).results
    assert SEED_RULE_WARNING in results.warnings and "not GUM" in SEED_RULE_WARNING
    assert results.verdict != "PASS"
    assert SEED_RULE_WARNING not in printed_warnings(results)  # it blocks: never printed


def test_mcm_is_stored_per_line_and_a_failed_line_is_stated(recording) -> None:
    results = analyze(recording, mcm_trials=20_000).results
    n = len(results.lines)
    assert len(results.mcm) == 2 * n  # magnitude and phase at every line
    assert {m["quantity"] for m in results.mcm} == {"magnitude", "phase"}
    failed = [m for m in results.mcm if not m["validated"]]
    statements = mcm_statements(results)
    assert len(statements) == len(failed)
    entry = dict(results.mcm[0], validated=False, low=-0.0071, high=0.0072, gum_high=0.0070)
    forced = dataclasses.replace(results, mcm=(entry,))
    (text,) = mcm_statements(forced)
    assert "failed the JCGM 101 clause 8 check" in text and "[-0.71, +0.72] %" in text
    stored = type(results).from_dict(json.loads(json.dumps(results.to_dict())))
    assert stored.mcm == results.mcm


def _tolerance_5() -> Tolerances:
    from app.stand.dut import Band

    return dataclasses.replace(TOLERANCES, characteristic=(Band(1.0, 1e5, 5.0),))


def _full_budget(recording):
    from app.stand import config as stand_config

    return stand_config.load().budget


def _stand_cmc():
    """The built-in stand's CMC (issue 32: without one no run is PASS)."""
    from app.stand import config as stand_config

    return stand_config.load().cmc


def test_a_line_outside_the_reference_certificate_is_refused_unless_a_term_carries_it(
    recording,
) -> None:
    """Point 3: outside the reference's calibrated range the line is refused (blocking) by
    default; a stated 'reference_extrapolation' term (magnitude and phase) carries it."""
    from dsp.annex_a import ComponentKind
    from dsp.calibration import ReferenceChain
    from dsp.uncertainty import Budget, Component, Quantity

    estimate = analyze(recording).estimate
    s = recording.chain.sensitivity_at(np.array([160.0]))[0][0]
    chain = dataclasses.replace(
        ReferenceChain((20.0, 160.0, 5000.0), (s, s, s), (0.0, 0.0, 0.0)),
        reference_gain=recording.chain.reference_gain,
        dut_gain=recording.chain.dut_gain,
        skew_s=recording.chain.skew_s,
    )
    budget = _full_budget(recording)
    plain = compute_results(
        estimate, recording.plan, chain, budget, tolerance_percent=5.0, cmc=_stand_cmc()
    )
    outside = [w for w in plain.warnings if "outside the reference certificate" in w]
    assert [w.split(":")[0] for w in outside] == ["line 10 Hz", "line 12.5 Hz", "line 16 Hz"]
    assert all(": refused" in w for w in outside)
    assert with_verdict(plain, _tolerance_5()).verdict == "INDETERMINATE"
    terms = tuple(
        Component(
            f"reference extrapolation below 20 Hz ({q.value})",
            0.01 if q is Quantity.MAGNITUDE else 1.0,
            quantity=q,
            kind=(ComponentKind.REFERENCE_EXTRAPOLATION,),
            max_frequency_hz=19.9,
        )
        for q in (Quantity.MAGNITUDE, Quantity.PHASE)
    )
    carried = compute_results(
        estimate,
        recording.plan,
        chain,
        Budget((*budget.components, *terms)),
        tolerance_percent=5.0,
        cmc=_stand_cmc(),
    )
    texts = [w for w in carried.warnings if "outside the reference certificate" in w]
    assert len(texts) == 3 and all("stated extrapolation term" in w for w in texts)
    assert with_verdict(carried, _tolerance_5()).verdict == "PASS"
    assert all(w in printed_warnings(carried) for w in texts)
    # refused: not stated (issue 32 point 5); carried: stated, the term in its type B
    assert not plain.lines[0].stated and math.isnan(plain.lines[0].relative_type_b)
    assert carried.lines[0].stated
    wider = carried.lines[0].relative_type_b
    base = budget.type_b(carried.lines[0].frequency_hz, Quantity.MAGNITUDE)[0]
    assert wider == pytest.approx(math.hypot(base, 0.01 / math.sqrt(3)))


def test_a_run_refused_mid_way_exits_2_and_a_stopped_one_3() -> None:
    """Point 7: the stored-response refusal ("refused before it is played ... predicted
    displacement", a PreflightError inside the run) is bad input to the stand: exit 2. The
    exit status every face returns (app.procedure.outcome.exit_status)."""
    from app.procedure.errors import REFUSED_BEFORE
    from app.procedure.outcome import exit_status
    from app.records.run_record import RunRecord

    def aborted(reason: str | None) -> int:
        return int(exit_status(RunRecord(run_id="r", status="aborted", abort_reason=reason)))

    reason = (
        f"{REFUSED_BEFORE}stored stand response off by 70 % at its check: its drive at level "
        "would give a predicted displacement of 17.70 mm p-p (...): refused before it is played"
    )
    assert aborted(reason) == 2
    assert aborted("emergency stop") == 3
    assert aborted("interrupted (Ctrl-C)") == 3
    assert aborted(None) == 3
    assert aborted(f"the recording ended: {REFUSED_BEFORE}") == 3  # a prefix, not a find


def test_the_certificate_prints_every_warning_that_does_not_block(complete_run, tmp_path) -> None:
    """Point 2 and 5: whatever does not block is printed on the certificate, each once, and a
    line that failed JCGM 101 clause 8 gets its Monte Carlo interval (drawn from a stored run
    with two such entries put into its results in memory)."""
    from pypdf import PdfReader

    from app.certificate import CertificateInfo
    from app.certificate.load import load_stored_run
    from app.certificate.pdf import write_pdf

    run = load_stored_run(complete_run)
    hum = "line 50 Hz: mains hum at 50 Hz: 0.2 % of the line, measured in 2 drive-off periods"
    other = "a warning of no known kind"
    mcm = {
        "frequency_hz": 1000.0,
        "quantity": "magnitude",
        "trials": 1000000,
        "probability": 0.9545,
        "low": -0.0113,
        "high": 0.0114,
        "gum_high": 0.0107,
        "validated": False,
    }
    results = dataclasses.replace(
        run.results, warnings=(*run.results.warnings, hum, other, hum), mcm=(mcm,)
    )
    assert printed_warnings(results)[-2:] == [hum, other]  # each once
    info = CertificateInfo(
        customer="ACME Ltd",
        customer_address="1 Test Street, 00-001 Testtown",
        authorised_by="J. Smith",
        temperature_c=23.0,
        mounting="stud",
        certificate_number="T-1",
    )
    pdf = tmp_path / "c.pdf"
    write_pdf(dataclasses.replace(run, results=results), info, None, pdf)
    text = " ".join(" ".join(p.extract_text() for p in PdfReader(pdf).pages).split())
    assert "Warnings" in text and hum in text and other in text
    assert text.count("mains hum at 50 Hz: 0.2 %") == 1
    assert "Monte Carlo validation (JCGM 101)" in text
    assert "[-1.13, +1.14] %" in text and "±1.07 %" in text


def test_a_line_too_few_lsb_above_the_step_is_not_stated_in_a_run_and_read_back(
    recording,
) -> None:
    """Issue 32 point 2: the resolution warning a run gives a line under 20 LSB makes the line
    not stated (no number, no U, no verdict), never the reference line (its warning blocks the
    run); results stored with numbers for such a line read back as not stated."""
    from dsp.calibration import Results

    results = analyze(recording, tolerance_percent=5.0).results
    low, ref = results.lines[0], results.reference
    warning = (
        f"line {low.frequency_hz:g} Hz: DUT channel 9.24 LSB on its +-0.1 V range (< 20 LSB): "
        "resolution not stated; raise the level or use a smaller input range"
    )
    reference_warning = warning.replace(
        f"line {low.frequency_hz:g} Hz", f"line {ref.frequency_hz:g} Hz"
    )
    stored = results.to_dict()
    stored["warnings"] = [*stored["warnings"], warning, reference_warning]
    back = Results.from_dict(json.loads(json.dumps(stored)))
    first = back.lines[0]
    assert not first.stated and "DUT channel 9.24 LSB on its +-0.1 V range" in first.not_stated
    assert math.isnan(first.sensitivity_mv_per_ms2) and math.isnan(first.phase_deg)
    assert math.isnan(first.relative_expanded_uncertainty) and first.iso_verdict == "not stated"
    assert first.tolerance_verdict == "not stated"
    assert all(ln.stated for ln in back.lines[1:])  # the reference line among them
    assert back.reference.sensitivity_mv_per_ms2 == ref.sensitivity_mv_per_ms2
    # a warning for another frequency, or the preflight's "predicted:" form, states nothing away
    other = dict(
        stored,
        warnings=[
            *results.warnings,
            f"predicted: {warning}",
            warning.replace(f"{low.frequency_hz:g} Hz", "12345 Hz"),
        ],
    )
    assert all(ln.stated for ln in Results.from_dict(other).lines)
