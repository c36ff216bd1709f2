"""The enveloped XML signature of a reference DCC (a ds:Signature child of its root), verified
with signxml against the signer's certificate: the one given (PEM, out of band), else the one
the signature embeds (ds:X509Data). A signature that does not verify, or that does not cover the
whole certificate, is refused naming ds:Signature; a DCC without one is "unsigned"; a signature
without any certificate to check it against is stated as not verified.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING

from app.errors import Refusal

if TYPE_CHECKING:
    from cryptography.x509 import Certificate
    from lxml.etree import _Element

DS_NS = "http://www.w3.org/2000/09/xmldsig#"
SIGNATURE_PATH = "/dcc:digitalCalibrationCertificate/ds:Signature"


class SignatureError(Refusal):
    """A signature that is present and broken (or cannot be checked as given)."""


class SignatureState(StrEnum):
    """What the signature of a reference DCC proved (stored strings)."""

    UNSIGNED = "unsigned"
    VERIFIED = "verified"
    NOT_VERIFIED = "not verified"  # signed, no certificate to verify it with


@dataclass(frozen=True)
class Signature:
    """The signature's state, the signer (the certificate's subject) and whose certificate
    it was verified against ("given" or "embedded")."""

    state: SignatureState
    signer: str = ""
    against: str = ""

    def line(self) -> str:
        """ "signed by X, verified (the given certificate)", "unsigned", ..."""
        if self.state is SignatureState.UNSIGNED:
            return "unsigned"
        if self.state is SignatureState.NOT_VERIFIED:
            return "signed, not verified (no certificate given or embedded)"
        where = (
            "against the given certificate"
            if self.against == "given"
            else "against the certificate it embeds, not checked against a trust anchor"
        )
        return f"signed by {self.signer}, verified {where}"


def _subject(certificate: Certificate) -> str:
    from cryptography.x509.oid import NameOID

    names = certificate.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    organisations = certificate.subject.get_attributes_for_oid(NameOID.ORGANIZATION_NAME)
    name = str(names[0].value) if names else certificate.subject.rfc4514_string()
    organisation = str(organisations[0].value) if organisations else ""
    if organisation and organisation not in name:
        name += f" ({organisation})"
    return name


def _embedded(signature: _Element) -> bytes | None:
    found = signature.find(f"{{{DS_NS}}}KeyInfo/{{{DS_NS}}}X509Data/{{{DS_NS}}}X509Certificate")
    if found is None or not (found.text or "").strip():
        return None
    try:
        return base64.b64decode("".join((found.text or "").split()), validate=True)
    except ValueError:
        raise SignatureError(
            f"{SIGNATURE_PATH}/ds:KeyInfo/ds:X509Data/ds:X509Certificate: not base64"
        ) from None


def verify_signature(data: bytes, root: _Element, certificate_pem: bytes | None) -> Signature:
    """The signature of the DCC `data` (parsed: `root`), verified against `certificate_pem`
    when given, else against the certificate it embeds. SignatureError naming ds:Signature."""
    from cryptography import x509

    signatures = root.findall(f"{{{DS_NS}}}Signature")
    if not signatures:
        if certificate_pem is not None:
            raise SignatureError(
                f"{SIGNATURE_PATH}: a signer's certificate was given but the DCC is unsigned"
            )
        return Signature(SignatureState.UNSIGNED)
    if len(signatures) > 1:
        raise SignatureError(
            f"{SIGNATURE_PATH}: {len(signatures)} signatures; one enveloped signature is read"
        )
    try:
        if certificate_pem is not None:
            certificate = x509.load_pem_x509_certificate(certificate_pem)
            against = "given"
        else:
            der = _embedded(signatures[0])
            if der is None:
                return Signature(SignatureState.NOT_VERIFIED)
            certificate = x509.load_der_x509_certificate(der)
            against = "embedded"
    except ValueError as exc:
        raise SignatureError(
            f"{SIGNATURE_PATH}: the signer's certificate cannot be read ({exc})"
        ) from None
    _check(data, root, certificate)
    return Signature(SignatureState.VERIFIED, _subject(certificate), against)


def _check(data: bytes, root: _Element, certificate: Certificate) -> None:
    """signxml's verification of the enveloped signature; it must sign the whole DCC."""
    from lxml import etree
    from signxml import SignatureConfiguration, XMLVerifier
    from signxml.exceptions import SignXMLException

    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False)
    try:
        result = XMLVerifier().verify(
            data,
            x509_cert=certificate,
            parser=parser,
            expect_config=SignatureConfiguration(location="./"),
        )
    except SignXMLException as exc:
        raise SignatureError(f"{SIGNATURE_PATH}: the signature does not verify ({exc})") from None
    except (ValueError, etree.LxmlError) as exc:
        raise SignatureError(f"{SIGNATURE_PATH}: the signature cannot be read ({exc})") from None
    results = result if isinstance(result, list) else [result]
    if not any(getattr(r.signed_xml, "tag", None) == root.tag for r in results):
        raise SignatureError(
            f"{SIGNATURE_PATH}: the signature does not cover the whole certificate (its "
            'reference is not the document, URI="")'
        )
