"""The triaxial certificate section (issue 36 point 3): printed once (GUM rounding) for the PDF
and the DCC; the DCC with the section valid against the shipped DCC 3.3.0 schema and saying
what the section prints; the PDF section drawn with its tables' text."""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from pypdf import PdfReader

from app.certificate import CertificateError, CertificateInfo, dcc
from app.certificate.load import load_stored_run
from app.certificate.triaxial import direction_text, printed, printed_triaxial, stored_triaxial
from app.certificate.triaxial_dcc import REF_LARGEST, REF_RATIO, add_triaxial, extension
from app.certificate.triaxial_pdf import sample_pdf
from dsp.triaxial import TriaxialResult, triaxial_result
from tests.dsp import triaxial_sim

NS = {"dcc": dcc.DCC_NS, "si": dcc.SI_NS}
INFO = CertificateInfo(
    customer="ACME Ltd",
    customer_address="1 Test Street, 00-001 Testtown",
    authorised_by="J. Smith",
    temperature_c=23.0,
    mounting="cube fixture, stud, 2 N m",
    certificate_number="C-TRI-1",
    issue_date="2026-11-28",
    dut_serial="TRI-1",
    dut_model="simulated triaxial",
)


@pytest.fixture(scope="module")
def result() -> TriaxialResult:
    plan = triaxial_sim.plan()
    runs = triaxial_sim.simulate(plan, seed=11)
    return triaxial_result(runs, triaxial_sim.BUDGET, triaxial_sim.TABLE_STATED)


def test_printed_rounds_per_gum_and_says_not_stated():
    assert printed(1.93456, 0.1623, 2.0) == printed(1.93456, 0.1623, 2.0)
    p = printed(1.93456, 0.1623, 2.0001)
    assert (p.value, p.expanded, p.k) == ("1.93", "0.16", "2.00")
    assert not printed(math.nan, 0.1, 2.0).stated
    assert not printed(1.0, 0.0, 2.0).stated  # no U: not stated


def test_the_section_prints_each_axis_the_matrix_and_the_largest_transverse(result):
    section = printed_triaxial(result)
    assert section.reference_frequency == "160"
    assert [a.axis for a in section.axes] == ["x", "y", "z"]
    assert [(a.towards_k, a.towards_l) for a in section.axes] == [
        ("y", "z"),
        ("z", "x"),
        ("x", "y"),
    ]
    x = section.axes[0]
    i = result.reference_index
    assert x.lines[i].deviation.value == "0"  # the reference line: 0 by definition
    assert float(x.largest_at_reference.value) == pytest.approx(2.0, abs=0.5)
    assert direction_text(x).startswith(f"axis x: {x.largest_at_reference.value} % ± ")
    assert "from +y towards +z" in direction_text(x)
    entry = section.matrix[0][0]
    assert float(entry.magnitude.value) == pytest.approx(10.2, rel=0.01)


def _quantities(xml: bytes) -> dict[str, ET.Element]:
    root = ET.fromstring(xml)
    return {
        q.findtext("dcc:name/dcc:content", namespaces=NS) or "": q
        for q in root.iterfind(".//dcc:quantity", NS)
    }


def test_the_dcc_with_the_section_validates_and_states_what_the_pdf_prints(
    result, complete_run: Path
):
    run = load_stored_run(complete_run)
    xml = dcc.build(run, INFO, extension(result))  # raises DccError when not valid
    assert dcc.validation_error(xml) is None
    root = ET.fromstring(xml)
    section = printed_triaxial(result)
    for axis in section.axes:
        found = root.find(f".//dcc:result[@id='triaxial-{axis.axis}']", NS)
        assert found is not None
    q = _quantities(xml)
    ratio = q["Axis x: transverse sensitivity ratio towards y"]
    assert ratio.get("refType") == REF_RATIO
    values = ratio.findtext("si:realListXMLList/si:valueXMLList", namespaces=NS).split()
    assert values == [ln.ratio_k.value for ln in section.axes[0].lines]
    u = ratio.findtext(".//si:valueExpandedMUXMLList", namespaces=NS).split()
    assert u == [ln.ratio_k.expanded for ln in section.axes[0].lines]
    largest = q["Axis y: largest transverse sensitivity at the reference frequency"]
    assert largest.get("refType") == REF_LARGEST
    assert largest.findtext("si:real/si:value", namespaces=NS) == (
        section.axes[1].largest_at_reference.value
    )
    entry = root.find(".//dcc:quantity[@id='S-x-y']", NS)
    assert entry is not None
    assert entry.findtext("si:real/si:value", namespaces=NS) == section.matrix[0][1].magnitude.value
    assert entry.findtext(".//si:valueExpandedMU", namespaces=NS) == (
        section.matrix[0][1].magnitude.expanded
    )


def test_a_line_not_stated_leaves_the_axis_lists_and_is_named(result):
    axis = result.axes[2]
    cut = np.array(axis.largest_percent.expanded)
    cut[0] = math.nan  # the 10 Hz line's largest transverse not stated
    largest = dataclasses.replace(axis.largest_percent, expanded=cut)
    changed = dataclasses.replace(
        result, axes=(*result.axes[:2], dataclasses.replace(axis, largest_percent=largest))
    )
    results = ET.Element(f"{{{dcc.DCC_NS}}}results")
    add_triaxial(results, changed)
    z = results.find("dcc:result[@id='triaxial-z']", NS)
    assert z is not None
    assert "10 Hz" in (z.findtext("dcc:description/dcc:content", namespaces=NS) or "")
    frequencies = z.findtext(".//si:valueXMLList", namespaces=NS).split()
    assert "10" not in frequencies and len(frequencies) == len(result.frequency_hz) - 1


def test_the_pdf_section_draws_the_matrix_and_each_axis(result, tmp_path: Path):
    out = tmp_path / "triaxial.pdf"
    sample_pdf(result, out, "C-TRI-1", "Test Laboratory")
    reader = PdfReader(out)
    words = " ".join(page.extract_text() for page in reader.pages)
    section = printed_triaxial(result)
    assert "Sensitivity matrix at the reference frequency 160 Hz" in words
    for axis in ("x", "y", "z"):
        assert f"Axis {axis}: transverse sensitivity" in words
    assert (
        f"{section.matrix[1][2].magnitude.value} ± {section.matrix[1][2].magnitude.expanded}"
        in words
    )
    assert direction_text(section.axes[2]) in words.replace("\n", " ")
    assert "page 1 of" in words


def test_nine_stored_runs_are_loaded_as_a_certificate_reads_them(complete_run: Path, tmp_path):
    """The seam for the certificate's assembly: nine run folders (here one run standing for
    all nine: every ratio is then 1, the matrix all ones times its sensitivity)."""
    folders = {o: {j: complete_run for j in "xyz"} for o in "xyz"}
    tri = stored_triaxial(folders, triaxial_sim.TABLE_STATED)
    stored = load_stored_run(complete_run).results
    i = tri.reference_index
    assert tri.axes[0].sensitivity_mv_per_ms2.value[i] == pytest.approx(
        stored.reference.sensitivity_mv_per_ms2
    )
    np.testing.assert_allclose(tri.axes[1].transverse[0].magnitude_percent.value, 100.0)
    missing = {o: dict(folders[o]) for o in folders}
    del missing["y"]["z"]
    with pytest.raises(CertificateError, match=r"orientation 'y', channel 'z': no run folder"):
        stored_triaxial(missing, triaxial_sim.TABLE_STATED)
    empty = tmp_path / "not-a-run"
    empty.mkdir()
    missing["y"]["z"] = empty
    with pytest.raises(CertificateError, match=r"orientation 'y', channel 'z': "):
        stored_triaxial(missing, triaxial_sim.TABLE_STATED)
