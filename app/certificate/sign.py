"""Signing certificates: PAdES signatures with the lab's key (pyHanko); checking them is
app.certificate.verify.

The signature is the last thing written to a certificate PDF (an incremental update over the
finished document with its DCC attachment), so any later change of a byte breaks it. A key
whose certificate is expired or not yet valid is refused before anything is signed.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.certificate.pdf_signature import SignatureStructureError, check_layout
from app.errors import Refusal

PASSWORD_ENV = "ACCELCAL_SIGN_PASSWORD"


class SigningError(Refusal):
    """A key that cannot be used or a PDF that cannot be signed; the message says why."""


@dataclass(frozen=True)
class Signer:
    """The lab's signing key and certificate chain, loaded from a PKCS#12 file."""

    path: Path
    signer: Any

    @classmethod
    def load(cls, path: Path, password: str | None = None) -> Signer:
        """The key in `path` (PKCS#12), its password from `password` or $ACCELCAL_SIGN_PASSWORD."""
        from pyhanko.sign import signers

        if not path.is_file():
            raise SigningError(f"--sign: no such file {path}")
        secret = password if password is not None else os.environ.get(PASSWORD_ENV)
        try:
            signer = signers.SimpleSigner.load_pkcs12(
                str(path), passphrase=secret.encode() if secret else None
            )
        except Exception as exc:  # pyHanko reports a wrong password or format variously
            raise SigningError(f"--sign: {path}: cannot load the key ({exc})") from None
        if signer is None:
            raise SigningError(
                f"--sign: {path}: cannot load the key (wrong password? set ${PASSWORD_ENV})"
            )
        from app.certificate.verify import SignerInfo

        info = SignerInfo.of(signer.signing_cert)
        problem = info.validity_problem()
        if problem is not None:
            raise SigningError(
                f"--sign: {path}: the key's certificate is {problem} ({info.subject})"
            )
        return cls(path, signer)

    def sign_in_place(self, pdf: Path, reason: str) -> None:
        """Sign `pdf` (PAdES baseline B) as its last revision."""
        from pyhanko.pdf_utils.incremental_writer import IncrementalPdfFileWriter
        from pyhanko.sign import fields, signers

        data = pdf.read_bytes()
        writer = IncrementalPdfFileWriter(io.BytesIO(data))
        meta = signers.PdfSignatureMetadata(
            field_name="LaboratorySignature",
            reason=reason,
            subfilter=fields.SigSeedSubFilter.PADES,
        )
        signed = signers.sign_pdf(writer, meta, signer=self.signer).getvalue()
        try:  # what `verify` will require of it, checked before the file is kept
            check_layout(signed)
        except SignatureStructureError as exc:
            raise SigningError(f"--sign: the signed PDF would not verify ({exc})") from None
        pdf.write_bytes(signed)
