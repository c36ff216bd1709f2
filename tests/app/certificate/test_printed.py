"""One answer per concept (issue 22): the deviation band the GUI and the certificate draw, the
ILAC-G8 decision every face follows, and one certificate register."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

import app.certificate.pdf as pdf
from app.certificate import CertificateInfo, issue, load_stored_run
from app.certificate.dcc import line_values
from app.certificate.printed import printed_lines
from app.certificate.readback import items_from_dcc, parse_inert
from app.certificate.register_issue import issue_registered
from app.certificate.text import dcc_conformity
from app.cli import main
from app.gui.plots import characteristic as gui_characteristic
from app.io.hdf5 import write_recording
from app.procedure.phase_store import stored_phases
from app.procedure.run import RunRequest, execute
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.records.register import REGISTER_NAME, read_register
from app.records.run_start import RunStart
from dsp import conformity
from dsp.calibration import LineResult, ReferenceResult, Results
from dsp.multisine import preset_plan
from tests.records_db import new_records
from tests.synthetic import lowpass_response, make_recording

# Hand values: U(dev) = (1 + dev) * U_rel(S). Line 2: +20 % with U_rel 2.5 % -> 1.2 * 2.5 = 3.0 %;
# line 3: -10 % with U_rel 2 % -> 0.9 * 2 = 1.8 %; the reference line: 0 % with 1 % -> 1.0 %.
# (100 * U_rel alone would give 2.5 % and 2.0 %.)
DEVIATIONS = (0.0, 20.0, -10.0)
U_REL = (0.01, 0.025, 0.02)
HAND_BAND = [1.0, 3.0, 1.8]


def _results() -> Results:
    lines = []
    for k, (f, dev, u_rel) in enumerate(
        zip((160.0, 1000.0, 2500.0), DEVIATIONS, U_REL, strict=True)
    ):
        s = 10.0 * (1 + dev / 100)
        lines.append(
            LineResult(
                nominal_frequency_hz=f,
                frequency_hz=f,
                sensitivity_mv_per_ms2=s,
                sensitivity_db=20 * math.log10(s),
                deviation_percent=dev,
                deviation_db=20 * math.log10(1 + dev / 100),
                phase_deg=-0.5 * k,
                relative_type_a=0.0,
                relative_type_b=u_rel / 2,
                relative_standard_uncertainty=u_rel / 2,
                relative_expanded_uncertainty=u_rel,
                expanded_uncertainty_mv_per_ms2=s * u_rel,
                coverage_factor=2.0,
                effective_dof=math.inf,
                phase_expanded_uncertainty_deg=0.4,
                phase_coverage_factor=2.0,
                coherence=1.0,
                reference_snr_db=80.0,
                dut_snr_db=80.0,
                dut_distortion_percent=0.0,
                iso_limit=0.02,
                iso_verdict="within",
            )
        )
    r = lines[0]
    reference = ReferenceResult(
        160.0, 160.0, r.sensitivity_mv_per_ms2, r.sensitivity_db, 0.1, 0.01, 2.0, 0.9545, 0.0, 0.4
    )
    return Results("periodic", 8, 6000.0, 12000, 0.9545, "gum", reference, tuple(lines))


def test_the_gui_and_the_certificate_draw_the_same_deviation_band(monkeypatch):
    results = _results()
    gui = gui_characteristic(results).deviation_expanded_percent.tolist()
    drawn: dict[str, list[float]] = {}
    real_chart = pdf.chart

    def spy(frequencies, values, half_widths, y_label, *rest):
        drawn[y_label] = list(half_widths)
        return real_chart(frequencies, values, half_widths, y_label, *rest)

    monkeypatch.setattr(pdf, "chart", spy)
    pdf._charts(results)
    assert gui == pytest.approx(HAND_BAND, rel=1e-12)
    assert drawn["deviation in %"] == pytest.approx(HAND_BAND, rel=1e-12)
    # and as printed (PDF table, DCC, verify): U two significant digits, the value alike
    printed = printed_lines(results)
    assert [p.deviation_expanded for p in printed] == ["1.0", "3.0", "1.8"]
    assert [p.deviation for p in printed] == ["0.0", "+20.0", "-10.0"]
    assert line_values(printed)["u_dev"] == ["1.0", "3.0", "1.8"]


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A clean 8-period HDF5 recording: every tolerance check passes by itself."""
    rec = make_recording(
        preset_plan("piezo", optimiser=stored_phases),
        lowpass_response(corner_hz=50000.0),
        periods=8,
        dut_noise_v=2e-4,
        seed=5,
    )
    path = tmp_path_factory.mktemp("h5") / "recording.h5"
    write_recording(path, rec)
    return path


def _analyse(capsys, path) -> Results:
    code = main(["analyze", str(path), "--tolerance", "5", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return Results.from_dict(json.loads(out))


def _conformity_text(results: Results) -> str:
    assert results.tolerance_percent is not None
    return "\n".join(p.text for p in pdf._statements(results, CertificateInfo(), "95.45 %"))


def test_every_face_follows_the_one_ilac_g8_decision(capsys, monkeypatch, recording):
    honest = _analyse(capsys, recording)  # the control: a flat DUT within +-5 %
    judged = [ln.tolerance_verdict for ln in honest.lines if ln.tolerance_verdict is not None]
    assert len(judged) == len(honest.lines) - 1  # the reference line: 0 by definition, unchecked
    # this recording states no type B budget: its type A-only U is below a full budget's
    # plausible floor, so no line gets a conformity statement (issue 32 point 7) and the run
    # is results for review (issue 25), as the certificate says
    assert set(judged) == {"not stated"}
    assert all(ln.relative_expanded_uncertainty < 0.001 for ln in honest.lines)
    assert honest.verdict == "INDETERMINATE"
    honest_text = _conformity_text(honest)
    assert f"0 pass, 0 fail, 0 inconclusive, {len(judged)} not stated of {len(judged)}" in (
        honest_text
    )
    assert "conformity not stated" in honest_text
    assert "characteristic: not stated" in " ".join(honest.verdict_reasons)

    calls = []

    def always_fail(deviation, expanded, tolerance, floor=0.0):
        calls.append((deviation, expanded, tolerance))
        return conformity.Outcome.FAIL

    monkeypatch.setattr(conformity, "decide", always_fail)
    failed = _analyse(capsys, recording)
    assert calls  # it was asked, and nobody else decided
    assert failed.verdict == "FAIL"  # the CLI's overall verdict (app.procedure.verdict)
    assert {ln.tolerance_verdict for ln in failed.lines} == {"fail", None}  # dsp.calibration's
    text = _conformity_text(failed)  # the certificate states what was decided
    assert "the item <b>does not conform</b>" in text
    assert conformity.DECISION_RULE in text
    assert dcc_conformity(failed.verdict) == "fail"


@pytest.mark.integration
def test_one_register_the_database_with_records_the_json_file_without(tmp_path):
    url = new_records(tmp_path / "lab.sqlite")
    lab = Lab(open_engine(url), actor="t")
    lab.add_customer("ACME Ltd", "1 Main Street")
    lab.add_model(
        "Sim",
        "PZ-1",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5,
        frequency_min_hz=1,
        frequency_max_hz=10000,
        level_ms2=10.0,
    )
    lab.add_sensor("SN-42", model="PZ-1", owner="ACME Ltd")
    root = tmp_path / "runs"
    finished = execute(RunRequest(dut="piezo", dut_id="SN-42", periods=4, out=root))
    assert finished.status == "complete"
    run = root / str(finished.record.run_id)
    start = RunStart.read(run)  # the procedure wrote config.json through RunStart
    assert start.to_json() == (run / "config.json").read_text(encoding="utf-8")
    assert start.identity["dut"]["id"] == "SN-42" and start.laboratory
    info = CertificateInfo(
        authorised_by="J. Smith",
        dut_type="piezoelectric accelerometer",
        temperature_c=23.0,
        mounting="stud",
    )

    with_records = issue_registered(run, info, tmp_path / "db.pdf", url=url, prepared_by="t")
    assert (tmp_path / "db.pdf").exists()
    assert [c.number for c in Lab(open_engine(url)).register()] == [with_records.number]
    assert not (root / REGISTER_NAME).exists()  # the database is the one register
    assert read_register(root) == []

    plain = dataclasses.replace(info, customer="ACME Ltd", customer_address="1 Main Street")
    without = issue(run, plain, tmp_path / "plain.pdf")
    assert [e.number for e in read_register(root)] == [without.number]
    assert without.number == f"AC-{finished.record.run_id}"
    assert [c.number for c in Lab(open_engine(url)).register()] == [with_records.number]
    # the DCC beside it carries the deviation and its U as the PDF's table prints them
    printed = printed_lines(load_stored_run(run).results)
    rows = items_from_dcc(parse_inert((tmp_path / "plain.xml").read_bytes())).lines
    assert [r.u_dev for r in rows] == [p.deviation_expanded for p in printed]
    assert [r.dev for r in rows] == [p.deviation for p in printed] and len(printed) > 10


def test_a_line_not_stated_prints_n_s_in_every_value_and_u_cell():
    """Issue 32 point 5: a line outside the reference's calibrated range carries no number
    with U in the certificate's table, the DCC's strings or the charts."""
    from app.certificate.printed import Column, table_cells
    from dsp.calibration import not_stated_line

    results = _results()
    lines = (*results.lines[:2], not_stated_line(results.lines[2], "outside (10-2000 Hz)"))
    results = dataclasses.replace(results, lines=lines)
    last = printed_lines(results)[2]
    cells = dict(table_cells(last, phase_stated=True, in_g=True))
    assert cells.pop(Column.NOMINAL) == "2500" and cells.pop(Column.FREQUENCY) == "2500"
    assert set(cells.values()) == {"n/s"}
    assert gui_characteristic(results).frequency_hz.tolist() == [160.0, 1000.0]
    assert printed_lines(results)[1].sensitivity == "12.00"  # the stated lines as before
