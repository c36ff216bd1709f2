"""The QR code printed on a certificate: the address of its public verification page.

The address is `[laboratory] verify_url` of the stand file (the web view's /verify page) + the
certificate number + a code that only a holder of the certificate knows: an HMAC-SHA256 of the
number keyed with the run's manifest SHA-256 (which never leaves the lab), 80 bits in base32.
The web view recomputes the code from the records (runs.manifest_sha256) and shows the status
only when it matches, so certificate numbers, which are sequential, cannot be walked.

The certificate (app.certificate.pdf `verification_qr`, app.certificate.dcc) takes the run's
address from `verification_address(run, number)`: QR_SIZE_MM square on page 1 with the address
beside it, and a DCC statement; nothing when the stand file has no verify_url.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import io
import re
from typing import TYPE_CHECKING
from urllib.parse import quote

from app.errors import Refusal
from app.stand.config import ConfigError
from app.stand.config import check_verify_url as stand_check_verify_url

if TYPE_CHECKING:
    from app.certificate.load import StoredRun

QR_SIZE_MM = 22.0  # printed size: 25 modules of a version-2 code at about 0.8 mm each
CODE_BYTES = 10  # 80 bits: unguessable, short enough to type from a printed page
_SHA256_HEX = re.compile(r"^[0-9a-f]{64}$")


class QrError(Refusal):
    """A verify_url or manifest hash that cannot make a verification address."""


def verification_code(number: str, manifest_sha256: str) -> str:
    """The certificate's verification code: base32 (lower case, no padding) of the first
    CODE_BYTES of HMAC-SHA256(key = the run manifest's SHA-256, message = the number)."""
    key = manifest_sha256.strip().lower()
    if not _SHA256_HEX.match(key):
        raise QrError(f"manifest hash: not a SHA-256 in hex: {manifest_sha256!r}")
    digest = hmac.new(bytes.fromhex(key), number.encode("utf-8"), hashlib.sha256).digest()
    return base64.b32encode(digest[:CODE_BYTES]).decode("ascii").rstrip("=").lower()


def check_verify_url(verify_url: str) -> str:
    """`verify_url` without a trailing slash; QrError unless it is an absolute http(s) URL
    with no query or fragment (the rule of app.stand.config.check_verify_url, its one home)."""
    try:
        return stand_check_verify_url(verify_url)
    except ConfigError as exc:
        raise QrError(f"laboratory.verify_url: {exc}") from None


def verify_address(verify_url: str, number: str, manifest_sha256: str) -> str:
    """The public verification address of certificate `number`: verify_url/NUMBER?code=CODE."""
    base = check_verify_url(verify_url)
    code = verification_code(number, manifest_sha256)
    return f"{base}/{quote(number, safe='')}?code={code}"


def qr_png(address: str, *, scale: int = 8) -> bytes:
    """A PNG of the QR code of `address` (error correction M, a 4-module quiet zone),
    `scale` pixels per module."""
    import segno

    buffer = io.BytesIO()
    segno.make_qr(address, error="m").save(buffer, kind="png", scale=scale, border=4)
    return buffer.getvalue()


def qr_svg(address: str, *, scale: int = 4) -> str:
    """The QR code of `address` as an SVG document (for web pages)."""
    import segno

    buffer = io.BytesIO()
    segno.make_qr(address, error="m").save(buffer, kind="svg", scale=scale, border=4)
    return buffer.getvalue().decode("utf-8")


def verification_address(run: StoredRun, number: str) -> str | None:
    """The certificate's public verification address (app.certificate.qr) from the run's
    [laboratory] verify_url, keyed with its manifest's SHA-256; None without a verify_url."""
    from app.records.run_folder import MANIFEST_NAME, sha256_of

    url = run.record.stand.verify_url or run.start.verify_url
    if not url:
        return None
    return verify_address(str(url), number, sha256_of(run.path / MANIFEST_NAME))
