"""Issue 36 point 3's acceptance on the simulated stand: a triaxial DUT run in its three
orientations (`accelcal run --dut T=SN --orientation x|y|z` on sim/stand-triaxial.toml) gives
three main-axis characteristics and the transverse sensitivities within U of the simulator's
truth (sim/triaxial.py's S, not the stated terms), on one signed certificate that verifies
against its run, with a DCC whose triaxial values are the TriaxialResult's as printed."""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from app.certificate import dcc
from app.certificate.triaxial import printed_triaxial
from app.certificate.triaxial_issue import triaxial_result_of, triaxial_runs
from app.cli import main
from app.io.hdf5 import read_recording
from app.records.batch import read_batch
from sim.triaxial import example_sensor

pytestmark = pytest.mark.integration

STAND = Path(__file__).parents[3] / "sim" / "stand-triaxial.toml"
NS = {"dcc": dcc.DCC_NS, "si": dcc.SI_NS}
ITEMS = ["--customer", "ACME Ltd",
         "--customer-address", "1 Test Street, 00-001 Testtown",
         "--authorised-by", "J. Smith", "--temperature", "23",
         "--mounting", "cube fixture, stud",
         "--dut-model", "simulated triaxial (sim/triaxial.py)",
         "--spec-kind", "datasheet",
         "--spec-id", "simulated triaxial data sheet, rev. 1"]  # fmt: skip


def _wrap(deg: np.ndarray) -> np.ndarray:
    return (np.asarray(deg) + 180.0) % 360.0 - 180.0


def _run_three(tmp_path: Path, capsys) -> list[Path]:
    batches = []
    for o, after in (("x", "y"), ("y", "z"), ("z", None)):
        argv = ["run", "--stand", str(STAND), "--dut", "T=TRI-1", "--orientation", o]
        assert main([*argv, "--technician", "A. Tech", "--seed", "7"]) == 0
        out = capsys.readouterr().out
        if after is not None:
            assert f"next: mount T with its {after} axis along the exciter" in out
        else:
            assert "all three orientations of T measured" in out
        new = [
            p
            for p in (tmp_path / "runs").iterdir()
            if (p / "batch.json").exists() and p not in batches
        ]
        assert len(new) == 1
        batches.append(new[0])
    return batches


def test_a_triaxial_dut_in_three_orientations_gives_one_certificate_within_u_of_its_truth(
    tmp_path: Path, pki, sign_password, monkeypatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    batches = _run_three(tmp_path, capsys)
    for folder, o in zip(batches, "xyz", strict=True):
        batch = read_batch(folder)
        # the main axis first, every channel its own sealed run folder
        assert batch.members[0].channel == f"dut.T.{o}"
        assert sorted(m.channel for m in batch.members) == ["dut.T.x", "dut.T.y", "dut.T.z"]
        for m in batch.members:
            results = json.loads((tmp_path / "runs" / m.run_id / "results.json").read_text())
            assert results["status"] == "complete"
            # each channel's recording holds its truth S[j, o] (sim/triaxial.py's sensor)
            truth = read_recording(tmp_path / "runs" / m.run_id / "recording.h5").truth
            assert truth is not None
            j = "xyz".index(m.channel[-1])
            s = example_sensor().matrix(truth.frequency_hz)[:, j, "xyz".index(o)]
            np.testing.assert_allclose(truth.sensitivity_mv_per_ms2, np.abs(s), rtol=1e-9)

    runs = triaxial_runs(list(reversed(batches)))  # any order: each names its orientation
    result = triaxial_result_of(runs)
    assert not result.warnings  # the stand file states the table's transverse motion
    f = result.frequency_hz
    s = example_sensor().matrix(f)
    for j, axis in enumerate(result.axes):
        main_axis = axis.sensitivity_mv_per_ms2
        assert np.all(np.isfinite(main_axis.expanded))
        assert np.all(np.abs(main_axis.value - np.abs(s[:, j, j])) <= main_axis.expanded)
        phase = axis.phase_deg
        assert np.all(
            np.abs(_wrap(phase.value - np.degrees(np.angle(s[:, j, j])))) <= phase.expanded
        )
        k, k2 = (j + 1) % 3, (j + 2) % 3
        t = {o: s[:, j, o] / s[:, j, j] for o in (k, k2)}
        for ratio in axis.transverse:
            o = "xyz".index(ratio.towards.value)
            m = ratio.magnitude_percent
            assert np.all(np.abs(m.value - 100 * np.abs(t[o])) <= m.expanded), (j, o)
        big = axis.largest_percent
        truth_big = 100 * np.hypot(np.abs(t[k]), np.abs(t[k2]))
        assert np.all(np.abs(big.value - truth_big) <= big.expanded)
        angle = axis.angle_deg
        truth_angle = np.degrees(np.arctan2(t[k2].real, t[k].real))
        assert np.all(np.abs(_wrap(angle.value - truth_angle)) <= angle.expanded)
    # the sensor's transverse sensitivities: 2 %, 3.5 %, 1.2 % at 30, 140, -70 degrees
    r = result.reference_index
    assert [a.largest_percent.value[r] for a in result.axes] == pytest.approx(
        [2.0, 3.5, 1.2], abs=0.2
    )
    assert [a.angle_deg.value[r] for a in result.axes] == pytest.approx([30, 140, -70], abs=15)

    names = [str(b.name) for b in batches]
    assert main(["certificate", "--triaxial", *names, *ITEMS, "--sign", str(pki.key)]) == 0
    issued = capsys.readouterr().out
    assert "triaxial T=TRI-1" in issued
    run = runs.main_run
    pdf, xml_path = run / "certificate.pdf", run / "certificate.xml"
    assert pdf.exists() and xml_path.exists()
    assert main(["verify", str(pdf), "--run", str(run), "--trust", str(pki.ca)]) == 0
    assert "certificate verified" in capsys.readouterr().out
    # the run check for three runs: the section recomputed from the nine runs, value by value
    argv = ["verify", str(pdf), "--run", str(run), "--trust", str(pki.ca), "--triaxial", *names]
    assert main(argv) == 0
    assert "ok   triaxial section: equal to the nine runs" in capsys.readouterr().out
    entry = printed_triaxial(result).matrix[0][1].magnitude
    tampered = tmp_path / "tampered.xml"
    text = xml_path.read_text(encoding="utf-8")
    at = text.index('id="S-x-y"')
    value_at = text.index(f"<si:value>{entry.value}</si:value>", at)
    tampered.write_text(
        text[:value_at]
        + "<si:value>9.999</si:value>"
        + text[value_at + len(f"<si:value>{entry.value}</si:value>") :],
        encoding="utf-8",
    )
    assert main(["verify", str(tampered), "--triaxial", *names]) == 2
    assert "FAIL triaxial section: S[x, y]" in capsys.readouterr().out

    # read back from the DCC: the values are the TriaxialResult's, as printed
    section = printed_triaxial(result)
    root = ET.parse(xml_path).getroot()
    for row in section.matrix:
        for entry in row:
            q = root.find(f".//dcc:quantity[@id='S-{entry.row}-{entry.column}']", NS)
            assert q is not None
            assert q.findtext("si:real/si:value", namespaces=NS) == entry.magnitude.value
            assert q.findtext(".//si:valueExpandedMU", namespaces=NS) == entry.magnitude.expanded
    quantities = {
        q.findtext("dcc:name/dcc:content", namespaces=NS) or "": q
        for q in root.iterfind(".//dcc:quantity", NS)
    }
    for axis in section.axes:
        largest = quantities[
            f"Axis {axis.axis}: largest transverse sensitivity at the reference frequency"
        ]
        assert largest.findtext("si:real/si:value", namespaces=NS) == (
            axis.largest_at_reference.value
        )
        ratio = quantities[
            f"Axis {axis.axis}: transverse sensitivity ratio towards {axis.towards_k}"
        ]
        values = ratio.findtext("si:realListXMLList/si:valueXMLList", namespaces=NS).split()
        assert values == [ln.ratio_k.value for ln in axis.lines]
    assert math.isclose(
        float(section.matrix[0][0].magnitude.value),
        float(result.matrix[0][0].magnitude_mv_per_ms2),
        rel_tol=1e-3,
    )


def test_orientation_refusals_name_the_option(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    fixture4 = STAND.parent / "stand-fixture4.toml"
    argv = ["run", "--stand", str(fixture4), "--dut", "A=SN-1", "--orientation", "x"]
    assert main(argv) == 2
    assert "a single-axis position" in capsys.readouterr().err
    argv = ["run", "--stand", str(STAND), "--dut", "T=SN-1", "--dut", "U=SN-2"]
    assert main([*argv, "--orientation", "y"]) == 2
    assert "--orientation: give the triaxial DUT once" in capsys.readouterr().err
    assert main(["run", "--stand", str(STAND), "--dut", "T=SN-1"]) == 2
    assert "a triaxial position (three inputs); run it once per orientation" in (
        capsys.readouterr().err
    )
    assert main(["certificate", "--triaxial", "a", "b", "c", *ITEMS]) == 2
    assert "--triaxial: 'a' is not a batch folder" in capsys.readouterr().err
