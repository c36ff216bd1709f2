"""`accelcal verify` against an attacker (issue 23): each forged or hostile input is refused with
exit 2 and says what failed; the honest certificate, signed by a trusted lab key, verifies.

A throwaway PKI (tests/app/certificate/throwaway_ca.py): the lab's CA and key, another CA, a
self-signed "lab signer", an expired and a not-yet-valid lab key.
"""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from pypdf import PdfReader

from app.certificate.pdf_marks import read_marks
from app.certificate.readback import (
    PrintedError,
    differences,
    items_from_dcc,
    items_from_pdf,
    parse_inert,
)
from app.cli import main
from app.records.run_folder import write_manifest
from app.records.seal import write_seal
from tests.app.certificate.throwaway_ca import LAB_SIGNER, PASSWORD, make_ca, make_signer

ROOT = Path(__file__).resolve().parents[3]
ITEMS = ["--customer", "ACME Ltd",
         "--customer-address", "1 Test Street, 00-001 Testtown",
         "--prepared-by", "A. Tech", "--authorised-by", "J. Smith",
         "--temperature", "23", "--mounting", "stud"]  # fmt: skip


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("pki")
    lab = make_ca(tmp, "Test Lab CA")
    other = make_ca(tmp, "Some Other CA")
    return {
        "ca": lab.pem,
        "other_ca": other.pem,
        "lab": make_signer(tmp, "lab.p12", lab),
        "self_signed": make_signer(tmp, "self.p12", None),
        "other": make_signer(tmp, "other.p12", other),
        "expired": make_signer(tmp, "expired.p12", lab, valid_from_days=-60, valid_to_days=-1),
        "future": make_signer(tmp, "future.p12", lab, valid_from_days=2, valid_to_days=40),
    }


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("runs")
    argv = ["run", "--sim", "--dut", "piezo", "--dut-id", "SN-9", "--periods", "3", "--seed", "4"]
    assert main([*argv, "--out", str(out)]) == 0
    (folder,) = (p for p in out.iterdir() if p.is_dir())
    return folder


def _issue(run: Path, out: Path, key: Path | None) -> int:
    sign = ["--sign", str(key)] if key is not None else []
    mp = pytest.MonkeyPatch()
    mp.setenv("ACCELCAL_SIGN_PASSWORD", PASSWORD)
    try:
        return main(["certificate", str(run), "--out", str(out), *ITEMS, *sign])
    finally:
        mp.undo()


@pytest.fixture(scope="module")
def honest(run: Path, pki: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    pdf = tmp_path_factory.mktemp("honest") / "certificate.pdf"
    assert _issue(run, pdf, pki["lab"]) == 0
    return pdf


def _verify(capsys: pytest.CaptureFixture[str], *argv: str | Path) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(["verify", *map(str, argv)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _refused(code: int, out: str, err: str, reason: str) -> None:
    """Exit 2, the reason on the outcome line (or the one error line), no traceback."""
    assert code == 2
    assert "Traceback" not in err and "PathBuildingError" not in err
    if out:
        last = out.strip().splitlines()[-1]
        assert last.startswith("certificate NOT verified: ")
        assert re.search(reason, last), last
    else:
        assert len(err.strip().splitlines()) == 1 and re.search(reason, err), err


def test_the_honest_certificate_verifies_with_its_signer_named(
    honest: Path, run: Path, pki: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _verify(capsys, honest, "--run", run, "--trust", pki["ca"])
    assert code == 0, out
    assert f"ok   signer: Common Name: {LAB_SIGNER}, issued by Common Name: Test Lab CA" in out
    assert "ok   run seal recomputed and named by the certificate" in out
    assert out.strip().splitlines()[-1] == "certificate verified"
    assert err == ""


def test_without_trust_it_is_never_verified_but_the_signer_is_shown(
    honest: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _verify(capsys, honest)
    _refused(code, out, err, f"signature intact, signer NOT checked: Common Name: {LAB_SIGNER}")
    assert "certificate verified" not in out


def _forge_signature_gap(pdf: bytes) -> bytes:
    """The issue's forgery: an incremental update changing the serial in the document's
    metadata, and the signature's /Contents re-encoded as a literal string of the same size in
    the file but decoding to more bytes, so that len1 + len2 + 2 * len(contents) + 2 equals
    the new file length (pyHanko then reports ENTIRE_FILE coverage)."""
    from pypdf import PdfWriter
    from pypdf.generic import NameObject, TextStringObject

    writer = PdfWriter(io.BytesIO(pdf), incremental=True)
    info = writer._info.get_object()  # the document information dictionary
    info[NameObject("/Subject")] = TextStringObject(str(info["/Subject"]).replace("9", "8"))
    buffer = io.BytesIO()
    writer.write(buffer)
    forged = buffer.getvalue()
    assert forged.startswith(pdf) and len(forged) > len(pdf)
    _, len1, start2, len2 = map(
        int, re.search(rb"/ByteRange \[(\d+) (\d+) (\d+) (\d+)\]", pdf).groups()
    )
    gap = start2 - len1
    assert start2 + len2 == len(pdf)  # the honest signature covers the whole original
    if (gap + len(forged) - len(pdf)) % 2:
        forged += b"\n"
    update = len(forged) - len(pdf)
    decoded = (gap + update - 2) // 2  # len1 + len2 + 2 * decoded + 2 == len(forged)
    cms = bytes.fromhex(pdf[len1 + 1 : start2 - 1].decode())
    body = re.sub(rb"([()\\])", rb"\\\1", cms).replace(b"\r", b"\\r").replace(b"\n", b"\\n")
    extra_raw = gap - 2 - len(body)  # raw bytes of padding to write
    extra_decoded = decoded - len(cms)  # bytes they must decode to
    three, one = divmod(extra_raw - extra_decoded, 3)
    padding = b"\\000" * three + b"\\0" * one
    padding += b"\0" * (extra_decoded - three - one)
    literal = b"(" + body + padding + b")"
    assert len(literal) == gap
    return forged[:len1] + literal + forged[start2:]


def test_the_signature_gap_forgery_is_refused(
    honest: Path, pki: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pyhanko.pdf_utils.reader import PdfFileReader
    from pyhanko.sign.validation import SignatureCoverageLevel

    forged = tmp_path / "forged.pdf"
    forged.write_bytes(_forge_signature_gap(honest.read_bytes()))
    with forged.open("rb") as handle:  # the forgery is real: the length test is fooled
        (sig,) = PdfFileReader(handle, strict=False).embedded_signatures
        assert sig.evaluate_signature_coverage() == SignatureCoverageLevel.ENTIRE_FILE
    assert "SN-8" in str(PdfReader(forged).metadata.subject)  # and it changed a printed item
    code, out, err = _verify(capsys, forged, "--trust", pki["ca"])
    _refused(code, out, err, "not exactly the hex string of its /Contents")


@pytest.mark.parametrize("rewrite", ["padding", "lower case", "white space"])
def test_the_unsigned_contents_is_exactly_the_cms_structure_and_its_zero_padding(
    honest: Path, pki: dict[str, Path], tmp_path: Path, capsys, rewrite: str
) -> None:
    """Issue 33 point 6: nothing in the signature's gap is signed, so its hex string must be
    exactly what the signer writes: the CMS structure in upper-case hex, then zeros. Before,
    the padding could carry any bytes (and the digits change case or gain white space) and the
    PDF still verified."""
    from app.certificate.pdf_signature import check_layout, der_end

    data = honest.read_bytes()
    last = check_layout(data).last
    start, end = last.length1, last.start2
    gap = data[start:end]
    cms_end = 1 + 2 * int(der_end(bytes.fromhex(gap[1:-1].decode("ascii"))) or 0)
    assert set(gap[cms_end:-1]) == {ord("0")}  # the honest padding: zeros only
    if rewrite == "padding":
        new = gap[:cms_end] + b"DEADBEEF" + gap[cms_end + 8 :]
    elif rewrite == "lower case":
        new = gap[:cms_end].lower() + gap[cms_end:]
    else:
        new = gap[:-3] + b"\n\n>"
    assert len(new) == len(gap) and new != gap
    forged = tmp_path / "forged.pdf"
    forged.write_bytes(data[:start] + new + data[end:])
    code, out, err = _verify(capsys, forged, "--trust", pki["ca"])
    _refused(code, out, err, "not exactly its CMS structure followed by zero padding")


def test_a_revision_after_the_signature_is_refused(
    honest: Path, pki: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pypdf import PdfWriter
    from pypdf.generic import NameObject, TextStringObject

    writer = PdfWriter(io.BytesIO(honest.read_bytes()), incremental=True)
    writer._info.get_object()[NameObject("/Subject")] = TextStringObject("serial SN-8")
    appended = tmp_path / "appended.pdf"
    with appended.open("wb") as handle:
        writer.write(handle)
    code, out, err = _verify(capsys, appended, "--trust", pki["ca"])
    _refused(code, out, err, r"bytes follow the last signature's signed range")


@pytest.mark.parametrize(
    ("key", "reason"),
    [
        ("self_signed", "signer trusted by the given CA: Common Name: Vibration Calibration"),
        ("other", "signer trusted by the given CA: .*issuer Common Name: Some Other CA"),
    ],
)
def test_a_signer_the_lab_ca_did_not_issue_is_refused(
    key: str,
    reason: str,
    run: Path,
    pki: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    pdf = tmp_path / f"certificate-{key}.pdf"
    assert _issue(run, pdf, pki[key]) == 0
    code, out, err = _verify(capsys, pdf, "--run", run, "--trust", pki["ca"])
    _refused(code, out, err, reason)
    assert f"signer: Common Name: {LAB_SIGNER}" in out  # who claims to have signed, shown


@pytest.mark.parametrize(
    ("key", "reason"), [("expired", "is expired on"), ("future", "is not valid before")]
)
def test_an_expired_or_future_key_does_not_sign(
    key: str,
    reason: str,
    run: Path,
    pki: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    pdf = tmp_path / "certificate-x.pdf"
    capsys.readouterr()
    assert _issue(run, pdf, pki[key]) == 2
    err = capsys.readouterr().err
    assert "--sign:" in err and reason in err and len(err.strip().splitlines()) == 1
    assert not pdf.exists()


def _sign_with(pdf: Path, key: Path, field: str = "LaboratorySignature") -> None:
    """Sign `pdf` in place with `key` directly through pyHanko (no validity check)."""
    from pyhanko.pdf_utils.incremental_writer import IncrementalPdfFileWriter
    from pyhanko.sign import fields, signers

    signer = signers.SimpleSigner.load_pkcs12(str(key), passphrase=PASSWORD.encode())
    writer = IncrementalPdfFileWriter(io.BytesIO(pdf.read_bytes()))
    meta = signers.PdfSignatureMetadata(field_name=field, subfilter=fields.SigSeedSubFilter.PADES)
    data = signers.sign_pdf(writer, meta, signer=signer).getvalue()
    pdf.chmod(0o644)
    pdf.write_bytes(data)


def test_a_certificate_signed_with_an_expired_key_is_refused(
    run: Path, pki: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pdf = tmp_path / "certificate-unsigned.pdf"
    assert _issue(run, pdf, None) == 0
    _sign_with(pdf, pki["expired"])
    code, out, err = _verify(capsys, pdf, "--run", run, "--trust", pki["ca"])
    _refused(code, out, err, r"signer: Common Name: Vibration.*: expired on")


def test_a_modified_and_re_signed_certificate_is_refused(
    honest: Path, pki: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pypdf import PdfWriter
    from pypdf.generic import NameObject, TextStringObject

    writer = PdfWriter(io.BytesIO(honest.read_bytes()), incremental=True)
    writer._info.get_object()[NameObject("/Subject")] = TextStringObject("serial SN-8")
    pdf = tmp_path / "re-signed.pdf"
    with pdf.open("wb") as handle:
        writer.write(handle)
    _sign_with(pdf, pki["other"], field="Signature2")
    # even trusting the second signer's CA: the lab's earlier signature is not ignored
    code, out, err = _verify(capsys, pdf, "--trust", pki["other_ca"])
    _refused(code, out, err, f"an earlier signature by Common Name: {LAB_SIGNER} covers bytes")
    assert "ok   signer trusted by the given CA" in out  # the refusal is the earlier signature


def _edited_run(run: Path, tmp_path: Path) -> Path:
    """A copy of `run` whose first line's sensitivity was edited, with a new manifest."""
    copy = tmp_path / run.name
    shutil.copytree(run, copy)
    for path in [copy, *copy.iterdir()]:
        path.chmod(0o755 if path.is_dir() else 0o644)
    data = json.loads((copy / "results.json").read_text())
    line = data["results"]["lines"][0]
    line["sensitivity_mv_per_ms2"] *= 1.01
    (copy / "results.json").write_text(json.dumps(data))
    (copy / "manifest.json").unlink()
    write_manifest(copy)
    return copy


def test_an_edited_run_with_a_regenerated_manifest_is_refused(
    honest: Path,
    run: Path,
    pki: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    copy = _edited_run(run, tmp_path)
    code, out, err = _verify(capsys, honest, "--run", copy, "--trust", pki["ca"])
    _refused(
        code, out, err, r"run manifest verified: .*manifest.json: hash mismatch with the run's seal"
    )


def test_an_edited_run_with_a_regenerated_seal_is_refused(
    honest: Path,
    run: Path,
    pki: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    copy = _edited_run(run, tmp_path)
    (copy / "seal.json").unlink()
    write_seal(copy, run.name, "forged")
    code, out, err = _verify(capsys, honest, "--run", copy, "--trust", pki["ca"])
    _refused(code, out, err, r"run seal .*the certificate names seal [0-9a-f]{64}, the run's is")
    assert "FAIL DCC numbers equal the run's results: line 1 s: run" in out


def test_printed_values_are_compared_by_value_never_by_substring(honest: Path) -> None:
    reader = PdfReader(honest)
    text = "\n".join(page.extract_text() for page in reader.pages)
    xml = reader.attachments["certificate.xml"][0]
    pdf_items = items_from_pdf(read_marks(honest.read_bytes()))
    assert len(pdf_items.lines) == 25 and pdf_items.serial == "SN-9"
    assert differences(items_from_dcc(parse_inert(xml)), pdf_items, "DCC", "PDF") == []
    first = pdf_items.lines[0]
    assert first.s.startswith("10.") and f" {first.s[1:]} " not in f" {text} "
    frequencies = re.search(rb"<si:valueXMLList>([^<]*)</si:valueXMLList>", xml).group(1)
    attacks = {
        "line 1 s": xml.replace(f">{first.s} ".encode(), f">{first.s[1:]} ".encode(), 1),
        "line 1 f": xml.replace(frequencies, b" ".join(reversed(frequencies.split())), 1),
        "line 1 k": xml.replace(
            b"<si:coverageFactorXMLList>2.00", b"<si:coverageFactorXMLList>2.10"
        ),
        "serial": xml.replace(b"<dcc:value>SN-9<", b"<dcc:value>SN-8<"),
        "verdict": xml.replace(b"Overall verdict: PASS", b"Overall verdict: FAIL"),
    }
    for item, changed in attacks.items():
        assert changed != xml, item
        found = differences(items_from_dcc(parse_inert(changed)), pdf_items, "DCC", "PDF")
        assert any(d.startswith(f"{item}:") for d in found), (item, found)


@pytest.mark.parametrize(
    "xml",
    [
        b"/dev/stdin",
        b"/etc/passwd",
        b'<?xml version="1.0"?><!DOCTYPE a [<!ENTITY x SYSTEM "file:///etc/passwd">]><a>&x;</a>',
        b'<!DOCTYPE a [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;">]><a>&b;</a>',
        b"<a>" + b"x" * (5 << 20) + b"</a>",
    ],
)
def test_an_attachment_is_parsed_inertly_or_refused(xml: bytes) -> None:
    with pytest.raises(PrintedError):
        parse_inert(xml)


def test_a_signed_pdf_whose_dcc_names_a_path_is_refused_without_reading_it(
    run: Path, pki: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from pypdf import PdfWriter

    pdf = tmp_path / "certificate-path.pdf"
    assert _issue(run, pdf, None) == 0
    writer = PdfWriter(clone_from=str(pdf))
    writer.root_object["/Names"]["/EmbeddedFiles"]["/Names"].clear()
    writer.add_attachment("certificate.xml", b"/dev/stdin")
    pdf.chmod(0o644)
    with pdf.open("wb") as handle:
        writer.write(handle)
    _sign_with(pdf, pki["lab"])
    code, out, err = _verify(capsys, pdf, "--trust", pki["ca"])
    _refused(code, out, err, "embedded DCC readable: not well-formed XML")


def _verify_process(*argv: str | Path, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "app", "verify", *map(str, argv)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        stdin=subprocess.DEVNULL,
    )


def test_a_fifo_a_device_and_an_oversized_file_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fifo = tmp_path / "fifo.pdf"
    os.mkfifo(fifo)
    done = _verify_process(fifo)  # a FIFO opened for reading would block: it must not
    assert done.returncode == 2 and "a FIFO (named pipe)" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    _refused(*_verify(capsys, "/dev/zero"), "character device")
    big = tmp_path / "big.pdf"
    with big.open("wb") as handle:
        handle.truncate(50 * (1 << 20) + 1)
    _refused(*_verify(capsys, big), r"52428801 bytes is more than a certificate PDF can hold")


def test_sixteen_megabytes_of_junk_end_in_bounded_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rng = np.random.default_rng(23)
    for name, head, tail in (("junk", b"", b""), ("pdfjunk", b"%PDF-1.7\n", b"\n%%EOF\n")):
        junk = tmp_path / f"{name}.pdf"
        junk.write_bytes(head + rng.bytes(16 << 20) + tail)
        started = time.monotonic()
        _refused(*_verify(capsys, junk), "signature")
        assert time.monotonic() - started < 5


@pytest.mark.parametrize("kind", ["fifo", "link to /dev/zero"])
def test_a_special_file_in_the_run_folder_is_refused_by_name(
    kind: str, honest: Path, run: Path, pki: dict[str, Path], tmp_path: Path
) -> None:
    copy = tmp_path / run.name
    shutil.copytree(run, copy)
    copy.chmod(0o755)
    (copy / "run.log").chmod(0o644)
    (copy / "run.log").unlink()
    if kind == "fifo":
        os.mkfifo(copy / "run.log")
    else:
        (copy / "run.log").symlink_to("/dev/zero")
    done = _verify_process(honest, "--run", copy, "--trust", pki["ca"])
    assert done.returncode == 2, done.stdout
    last = done.stdout.strip().splitlines()[-1]
    reason = "a FIFO" if kind == "fifo" else "a symbolic link"
    assert "run manifest verified" in last and f"run.log: is {reason}" in last
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("target", ["/etc/passwd", "fifo"])
def test_an_hdf5_dataset_stored_outside_the_file_is_refused(
    target: str, run: Path, tmp_path: Path
) -> None:
    from app.io.hdf5 import RecordingError, read_recording

    if target == "fifo":
        target = str(tmp_path / "samples.fifo")
        os.mkfifo(target)
    path = tmp_path / "recording.h5"
    shutil.copy(run / "recording.h5", path)
    path.chmod(0o644)
    with h5py.File(path, "a") as f:
        del f["signals/reference"]
        f["signals"].create_dataset(
            "reference", shape=(64,), dtype="f8", external=[(target, 0, 64 * 8)]
        )
    with pytest.raises(RecordingError, match=r"/signals/reference: dataset stored outside"):
        read_recording(path)


# --- the byte layout, on hand-made files ------------------------------------------------------


def _signed_bytes(
    gap: bytes = b"<3082abcd0000>",
    tail: bytes = b"",
    key: bytes = b"/Contents ",
    before: bytes = b"%PDF-1.7\n",
) -> bytes:
    """A minimal 'signed file': `before` (a header, or a whole earlier file and an update), a
    signature dictionary whose /ByteRange leaves out exactly `gap` (after `key`), a trailer;
    then `tail`. Numbers are fixed-width, so the offsets fit into the bytes they describe."""
    head = before + b"1 0 obj\n<< /Type /Sig /ByteRange [0 A B C] " + key
    head = head.replace(b"A B C", b"%010d %010d %010d" % (0, 0, 0))
    rest = b" >>\nendobj\ntrailer\n<< >>\n%%EOF\n"
    length1, start2 = len(head), len(head) + len(gap)
    numbers = b"%010d %010d %010d" % (length1, start2, len(rest))
    head = head[: -len(key) - 34] + numbers + b"] " + key
    return head + gap + rest + tail


def test_the_layout_of_a_hand_made_signed_file() -> None:
    from app.certificate.pdf_signature import check_layout

    data = _signed_bytes()
    layout = check_layout(data)
    assert layout.last.contents == bytes.fromhex("3082abcd0000") and layout.earlier == ()
    assert layout.last.end == len(data)
    layout.check_is([0, layout.last.length1, layout.last.start2, layout.last.length2],
                    bytes.fromhex("3082abcd0000"))  # fmt: skip


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (_signed_bytes(gap=b"(0\\202abcd)"), "not exactly the hex string"),
        (_signed_bytes(gap=b"<3082abcd> "), "not exactly the hex string"),
        (_signed_bytes(gap=b" <3082abcd>"), "not exactly the hex string"),
        (_signed_bytes(gap=b"<3082abc>"), "not exactly the hex string"),  # odd digits
        (_signed_bytes(gap=b"<3082abcd>", key=b"/Foo "), "not exactly the hex string"),
        (_signed_bytes(tail=b"\n"), "1 bytes follow the last signature's signed range"),
        (_signed_bytes().replace(b"[0 ", b"[1 "), "does not describe this"),
        (b"%PDF-1.7\nno signature\n%%EOF\n", "not signed"),
    ],
)
def test_a_layout_that_proves_nothing_is_refused(data: bytes, reason: str) -> None:
    from app.certificate.pdf_signature import SignatureStructureError, check_layout

    with pytest.raises(SignatureStructureError, match=reason):
        check_layout(data)


def test_the_signed_range_must_be_the_signature_fields() -> None:
    from app.certificate.pdf_signature import SignatureStructureError, check_layout

    layout = check_layout(_signed_bytes())
    r = layout.last
    for byte_range, contents in (
        ([0, r.length1, r.start2, r.length2 - 1], r.contents),
        ([0, r.length1, r.start2, r.length2], b"\x30\x82\xab\xcd"),
    ):
        with pytest.raises(SignatureStructureError, match="not the /ByteRange and /Contents"):
            layout.check_is(byte_range, contents or b"")


def test_an_earlier_signature_is_described_with_what_came_after() -> None:
    from app.certificate.pdf_signature import check_layout

    first = _signed_bytes()
    update = b"7 0 obj\n<< >>\nendobj\n12 0 obj\n<< >>\nendobj\n"
    data = _signed_bytes(gap=b"<3082ef00>", before=first + update)
    layout = check_layout(data)
    assert layout.last.contents == bytes.fromhex("3082ef00")
    (earlier,) = layout.earlier
    assert earlier.covered_bytes == len(first)
    assert earlier.added_bytes == len(data) - len(first)
    assert earlier.changed_objects == (1, 7, 12)  # the update's and the new signature's
    assert f"covers bytes 0-{len(first)}; {len(data) - len(first)} bytes" in earlier.describe()


def test_a_check_that_runs_too_long_is_stopped(
    honest: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import app.certificate.verify as verify_module

    def slow(*args: object) -> bool:
        time.sleep(5)
        return True

    monkeypatch.setattr(verify_module, "TIME_LIMIT_S", 0.2)
    monkeypatch.setattr(verify_module, "_check_signature", slow)
    started = time.monotonic()
    code, out, err = _verify(capsys, honest)
    assert time.monotonic() - started < 3
    _refused(code, out, err, r"the check took longer than 0.2 s and was stopped")
