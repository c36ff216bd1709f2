"""The byte structure of a signed PDF, read from the file's bytes, trusting no length sum.

A PDF signature signs the bytes named by its /ByteRange [0 a b c]: everything but the gap
[a, b), which must hold exactly the hex string `<...>` that is the signature's /Contents. This
module finds every /ByteRange in the raw bytes (also those of signatures a later revision no
longer lists), checks that the last one covers the whole file but exactly its own /Contents hex
string (a literal string, any other byte in the gap or any byte after the range is refused),
and describes each earlier signature with what was changed after it. Offsets are in bytes.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

from app.errors import Refusal

_BYTE_RANGE = re.compile(
    rb"/ByteRange\s*\[\s*(\d{1,12})\s+(\d{1,12})\s+(\d{1,12})\s+(\d{1,12})\s*\]"
)
_HEX_STRING = re.compile(rb"<([0-9A-Fa-f\s]*)>")
_CONTENTS_KEY = re.compile(rb"/Contents\s*\Z")
_CANONICAL_HEX = re.compile(rb"<([0-9A-F]*)>")  # as the signer writes it: upper case, no space
_OBJECT_HEADER = re.compile(rb"(?<![0-9])(\d{1,10})\s+(\d{1,5})\s+obj\b")


class SignatureStructureError(Refusal):
    """A signed PDF whose byte layout does not prove what the signature covers; says why."""


@dataclass(frozen=True)
class ByteRange:
    """One signature's /ByteRange [0, length1, start2, length2] (bytes) and its /Contents
    decoded from the hex string in the gap (None when the gap holds no hex string)."""

    at: int  # where the /ByteRange array is in the file
    length1: int
    start2: int
    length2: int
    contents: bytes | None

    @property
    def end(self) -> int:
        """The first byte after the signed range."""
        return self.start2 + self.length2


@dataclass(frozen=True)
class EarlierSignature:
    """A signature before the last one: who signed it and what was changed after it."""

    signer: str
    covered_bytes: int
    added_bytes: int
    changed_objects: tuple[int, ...]

    def describe(self) -> str:
        """One line: the signer, what it covers and the objects written after it."""
        objects = ", ".join(str(n) for n in self.changed_objects[:12])
        more = " ..." if len(self.changed_objects) > 12 else ""
        return (
            f"an earlier signature by {self.signer} covers bytes 0-{self.covered_bytes}; "
            f"{self.added_bytes} bytes were added after it"
            + (f", writing objects {objects}{more}" if objects else "")
        )


@dataclass(frozen=True)
class SignedLayout:
    """The last signature's checked byte range and the signatures before it."""

    last: ByteRange
    earlier: tuple[EarlierSignature, ...]

    def check_is(self, byte_range: Sequence[int], contents: bytes) -> None:
        """SignatureStructureError unless the checked range is the one of the document's
        signature field as a PDF parser read it (its /ByteRange and /Contents)."""
        last = self.last
        if list(byte_range) != [0, last.length1, last.start2, last.length2] or (
            last.contents != contents
        ):
            raise SignatureStructureError(
                "the last signed range and its hex string are not the /ByteRange and "
                "/Contents of the document's signature field"
            )

    def check_contents(self, data: bytes) -> None:
        """SignatureStructureError unless the last signature's gap in `data` is exactly the
        hex string the signer writes: its CMS structure, then zero padding (issue 33)."""
        last = self.last
        problem = contents_problem(data[last.length1 : last.start2])
        if problem is not None:
            raise SignatureStructureError(
                f"the signature's /Contents (bytes {last.length1}-{last.start2}) is not exactly "
                f"its CMS structure followed by zero padding: {problem}"
            )


def byte_ranges(data: bytes) -> list[ByteRange]:
    """Every /ByteRange array in `data` with the /Contents hex string in its gap, by position.
    A /ByteRange that does not start at 0 or does not fit the file is refused."""
    found = []
    for match in _BYTE_RANGE.finditer(data):
        start1, length1, start2, length2 = (int(g) for g in match.groups())
        if start1 != 0 or not 0 < length1 < start2 <= len(data) or start2 + length2 > len(data):
            raise SignatureStructureError(
                f"a /ByteRange [{start1} {length1} {start2} {length2}] at byte {match.start()} "
                f"does not describe this {len(data)}-byte file"
            )
        found.append(
            ByteRange(match.start(), length1, start2, length2, _gap_contents(data, length1, start2))
        )
    return found


def _gap_contents(data: bytes, start: int, end: int) -> bytes | None:
    """The bytes of the hex string that fills data[start:end] exactly and follows a /Contents
    key, or None when the gap is anything else."""
    if not _CONTENTS_KEY.search(data[max(0, start - 64) : start]):
        return None
    match = _HEX_STRING.fullmatch(data, start, end)
    if match is None:
        return None
    digits = re.sub(rb"\s", b"", match.group(1))
    if len(digits) % 2:
        return None
    return bytes.fromhex(digits.decode("ascii"))


def check_layout(data: bytes) -> SignedLayout:
    """Check that the last signature in `data` covers the whole file except exactly the hex
    string of its /Contents, from the bytes alone (before any PDF parser reads the file).
    SignatureStructureError says what is wrong; the earlier signatures are returned for the
    caller to report. See `SignedLayout.check_is` for tying it to the signature field."""
    ranges = byte_ranges(data)
    if not ranges:
        raise SignatureStructureError("no /ByteRange in the file: the PDF is not signed")
    last = max(ranges, key=lambda r: (r.end, r.at))
    if last.contents is None:
        raise SignatureStructureError(
            f"the signature's gap (bytes {last.length1}-{last.start2}) is not exactly the hex "
            "string of its /Contents (a literal string or other bytes in the unsigned gap)"
        )
    if last.end != len(data):
        raise SignatureStructureError(
            f"{len(data) - last.end} bytes follow the last signature's signed range (a "
            "revision added after signing)"
        )
    if last.length1 <= last.at < last.start2:
        raise SignatureStructureError("the /ByteRange lies in the unsigned gap")
    earlier = tuple(_earlier(data, r) for r in ranges if r is not last)
    return SignedLayout(last, earlier)


def contents_problem(gap: bytes) -> str | None:
    """Why the unsigned gap `<...>` is not exactly the hex string the signer writes (upper-case
    digits, no white space) of one DER structure (a definite-length SEQUENCE: the CMS
    ContentInfo) followed by zero bytes only; None when it is. Nothing in the gap is signed, so
    any other byte there could be changed and the PDF would still verify."""
    match = _CANONICAL_HEX.fullmatch(gap)
    if match is None:
        return "its hex string holds white space, lower-case digits or other bytes"
    digits = match.group(1)
    if len(digits) % 2:
        return "an odd number of hex digits"
    contents = bytes.fromhex(digits.decode("ascii"))
    end = der_end(contents)
    if end is None:
        return "it does not start with one definite-length DER structure"
    tail = contents[end:]
    if tail.strip(b"\0"):
        first = end + next(i for i, b in enumerate(tail) if b)
        return f"{sum(1 for b in tail if b)} padding byte(s) are not zero (first at byte {first})"
    return None


def der_end(data: bytes) -> int | None:
    """Where the DER SEQUENCE at the start of `data` ends (its header and content), or None
    when `data` does not start with one of definite length that fits."""
    if len(data) < 2 or data[0] != 0x30:
        return None
    first = data[1]
    if first < 0x80:
        header, length = 2, first
    else:
        count = first & 0x7F
        if count == 0 or count > 4 or len(data) < 2 + count:
            return None  # 0x80: indefinite length (BER, not DER)
        header, length = 2 + count, int.from_bytes(data[2 : 2 + count], "big")
    end = header + length
    return end if end <= len(data) else None


def _earlier(data: bytes, signed: ByteRange) -> EarlierSignature:
    """Who made the earlier signature `signed` and which objects the bytes after it write."""
    tail = data[signed.end :]
    objects = sorted({int(m.group(1)) for m in _OBJECT_HEADER.finditer(tail)})
    return EarlierSignature(_signer_of(signed.contents), signed.end, len(tail), tuple(objects))


def _signer_of(contents: bytes | None) -> str:
    """The subject of the certificate that made the CMS signature `contents`, or a note."""
    if not contents:
        return "an unreadable signer (its /Contents is no hex string)"
    try:
        from asn1crypto import cms

        signed_data = cms.ContentInfo.load(contents.rstrip(b"\0"))["content"]
        info = signed_data["signer_infos"][0]["sid"]
        for candidate in signed_data["certificates"]:
            cert = candidate.chosen
            if info.name == "issuer_and_serial_number" and (
                cert.serial_number == info.chosen["serial_number"].native
            ):
                return str(cert.subject.human_friendly)
        return "an unknown signer (no certificate in the signature)"
    except (ValueError, TypeError, KeyError, IndexError):
        return "an unreadable signer (a damaged signature)"
