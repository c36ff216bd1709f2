"""A triaxial sensor's certificate from its three orientation batches (issue 36 point 3):
`accelcal certificate --triaxial BATCH_X BATCH_Y BATCH_Z`.

Each batch is one orientation's run (app.procedure.triaxial): its first member is the channel
along the exciter (the orientation), the other two the cross channels. The three batches must
name one position and one serial and cover x, y and z once each (in any order). The nine run
folders make the TriaxialResult (app.certificate.triaxial.stored_triaxial) with the table's
transverse motion the stand file states for the position (`transverse_motion`, read from the
x run's stored stand.toml; none stated: the result says its ratios' U understates). The
certificate is issued by the certificate service on the x orientation's x channel run (its
number, register, two-person rule, signing) with the triaxial section in the PDF and the DCC.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from app.certificate.info import CertificateError
from dsp.triaxial import TriaxialResult
from dsp.uncertainty import Budget

log = logging.getLogger(__name__)

AXIS_NAMES = ("x", "y", "z")


@dataclass(frozen=True)
class TriaxialRuns:
    """The nine run folders `folders[orientation][channel]`, the position and the serial,
    and each orientation's batch id."""

    folders: dict[str, dict[str, Path]]
    position: str
    serial: str
    batches: dict[str, str]

    @property
    def main_run(self) -> Path:
        """The run the certificate is issued on: orientation x, channel x."""
        return self.folders["x"]["x"]


def _axis_of(channel: str, where: str) -> tuple[str, str]:
    """(position, axis) of a triaxial channel 'dut.<position>.<axis>'."""
    parts = channel.split(".")
    if len(parts) != 3 or parts[0] != "dut" or parts[2] not in AXIS_NAMES:
        raise CertificateError(f"{where}: channel {channel!r} is not a triaxial DUT's channel")
    return parts[1], parts[2]


def triaxial_runs(batches: Sequence[Path]) -> TriaxialRuns:
    """The three orientation batches' run folders (CertificateError naming the batch: not a
    batch, not a triaxial orientation, another position or serial, an orientation twice or
    missing)."""
    from app.records.batch import BatchError, read_batch

    if len(batches) != 3:
        raise CertificateError(f"--triaxial: give three batches (x, y, z), got {len(batches)}")
    folders: dict[str, dict[str, Path]] = {}
    ids: dict[str, str] = {}
    seen: set[tuple[str, str]] = set()
    for folder in batches:
        where = f"--triaxial {folder}"
        try:
            batch = read_batch(folder)
        except BatchError as exc:
            raise CertificateError(f"{where}: {exc}") from None
        if len(batch.members) != 3:
            raise CertificateError(f"{where}: {len(batch.members)} members, not a triaxial run")
        position, orientation = _axis_of(batch.members[0].channel, where)
        if orientation in folders:
            raise CertificateError(
                f"{where}: orientation {orientation!r} is also batch {ids[orientation]}"
            )
        folders[orientation] = {}
        for member in batch.members:
            p, axis = _axis_of(member.channel, where)
            seen.add((p, member.serial))
            folders[orientation][axis] = Path(folder).parent / member.run_id
        if set(folders[orientation]) != set(AXIS_NAMES):
            raise CertificateError(f"{where}: its members are not the channels x, y and z")
        ids[orientation] = batch.batch_id
    if len(seen) != 1:
        named = ", ".join(f"{p}={s}" for p, s in sorted(seen))
        raise CertificateError(f"--triaxial: the batches name different DUTs ({named})")
    position, serial = next(iter(seen))
    return TriaxialRuns(folders, position, serial, ids)


def stated_transverse(run: Path, position: str) -> Budget:
    """The table's transverse motion the run's stored stand file states for `position`
    (empty when it states none or the run stored no stand file)."""
    from app.stand import config as stand_config

    path = run / "stand.toml"
    if not path.is_file():
        return Budget()
    try:
        fixture = stand_config.load(path).fixture
    except (stand_config.ConfigError, ValueError, OSError) as exc:
        raise CertificateError(f"{path}: {exc}") from None
    if fixture is None:
        return Budget()
    try:
        return fixture.position(position).transverse_budget()
    except KeyError:
        return Budget()


def triaxial_result_of(runs: TriaxialRuns) -> TriaxialResult:
    """The TriaxialResult of the nine stored runs (app.certificate.triaxial.stored_triaxial)."""
    from app.certificate.triaxial import stored_triaxial
    from dsp.errors import InputRefused

    table = stated_transverse(runs.main_run, runs.position)
    try:
        return stored_triaxial(runs.folders, table)
    except InputRefused as exc:
        raise CertificateError(f"--triaxial: {exc}") from None


def section_differences(xml: bytes, result: TriaxialResult) -> list[str]:
    """Where the DCC `xml`'s triaxial section differs from `result` as printed: every matrix
    entry (magnitude, phase, their U), per axis the largest transverse sensitivity at the
    reference frequency and the transverse ratios' lists ([] when all are equal)."""
    import xml.etree.ElementTree as ET

    from app.certificate.dcc import DCC_NS, SI_NS
    from app.certificate.triaxial import printed_triaxial

    ns = {"dcc": DCC_NS, "si": SI_NS}
    root = ET.fromstring(xml)
    section = printed_triaxial(result)
    out: list[str] = []
    for row in section.matrix:
        for entry in row:
            q = root.find(f".//dcc:quantity[@id='S-{entry.row}-{entry.column}']", ns)
            if q is None:
                out.append(f"S[{entry.row}, {entry.column}]: not in the DCC")
                continue
            got = (
                q.findtext("si:real/si:value", namespaces=ns),
                q.findtext(".//si:valueExpandedMU", namespaces=ns),
            )
            want = (entry.magnitude.value, entry.magnitude.expanded)
            if entry.magnitude.stated and got != want:
                out.append(f"S[{entry.row}, {entry.column}]: DCC {got}, runs {want}")
    quantities = {
        q.findtext("dcc:name/dcc:content", namespaces=ns) or "": q
        for q in root.iterfind(".//dcc:quantity", ns)
    }
    for axis in section.axes:
        name = f"Axis {axis.axis}: largest transverse sensitivity at the reference frequency"
        q = quantities.get(name)
        want_big = axis.largest_at_reference.value
        if axis.largest_at_reference.stated and (
            q is None or q.findtext("si:real/si:value", namespaces=ns) != want_big
        ):
            out.append(f"{name}: the runs give {want_big}")
        for towards, cells in (
            (axis.towards_k, [ln.ratio_k.value for ln in axis.lines if ln.ratio_k.stated]),
            (axis.towards_l, [ln.ratio_l.value for ln in axis.lines if ln.ratio_l.stated]),
        ):
            name = f"Axis {axis.axis}: transverse sensitivity ratio towards {towards}"
            q = quantities.get(name)
            got_list = (
                (q.findtext("si:realListXMLList/si:valueXMLList", namespaces=ns) or "").split()
                if q is not None
                else []
            )
            if got_list != cells:
                out.append(f"{name}: the DCC's list differs from the runs'")
    return out


def dcc_of(path: Path) -> bytes:
    """The DCC XML of a certificate: the file itself (.xml), else the PDF's embedded
    certificate.xml (CertificateError when it has none)."""
    if path.suffix.lower() == ".xml":
        return path.read_bytes()
    from pypdf import PdfReader

    attachments = PdfReader(path).attachments
    found = attachments.get("certificate.xml")
    if not found:
        raise CertificateError(f"{path}: no embedded DCC (certificate.xml)")
    return bytes(found[0])
