"""The DCC's own signature (issue 35 point 3): an enveloped XML signature, XAdES baseline B
(ETSI EN 319 132-1: SigningTime and SigningCertificateV2 signed), made with the laboratory's
PKCS#12 key (the one that signs the PDF: app.certificate.sign.Signer) by `signxml`, so that a
DCC taken out of its PDF still proves who issued it and that not one value changed.

The signature is the DCC root's last child (`ds:Signature`, which DCC 3.3.0 allows there); its
one data reference is URI="" with the enveloped-signature transform (the whole document but the
signature), canonicalised by C14N 1.1; the key's certificate chain is in `ds:KeyInfo`. Signed
before the DCC is written beside the PDF and attached to it (app.certificate.issuing), and
checked (`check_dcc_signature`) by `accelcal verify`, alongside the PDF's PAdES: intact over
the whole DCC, by the PDF's signer, trusted when a CA is given (`--trust`).
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from app.errors import Refusal

DS_NS = "http://www.w3.org/2000/09/xmldsig#"
CHECK = "DCC signature (XAdES, enveloped)"
UNSIGNED_DETAIL = "the DCC is not signed: nothing proves who issued it"
_C14N_11 = "http://www.w3.org/2006/12/xml-c14n11"


class DccSigningError(Refusal):
    """A key that cannot sign a DCC, or a signed DCC that would not verify; says why."""


def _key_and_chain(signer: Any) -> tuple[Any, list[str]]:
    """The private key (cryptography) and the certificate chain (PEM strings, the signer's
    first) of an app.certificate.sign.Signer (pyHanko's SimpleSigner inside)."""
    from cryptography import x509
    from cryptography.hazmat.primitives.serialization import Encoding, load_der_private_key

    inner = signer.signer
    key = load_der_private_key(inner.signing_key.dump(), password=None)
    first = inner.signing_cert
    others = [c for c in (inner.cert_registry or []) if c.dump() != first.dump()]
    chain = [
        x509.load_der_x509_certificate(c.dump()).public_bytes(Encoding.PEM).decode("ascii")
        for c in (first, *others)
    ]
    return key, chain


def _algorithm(key: Any) -> str:
    """The signature algorithm of `key` (SHA-256 based); DccSigningError for another kind."""
    from cryptography.hazmat.primitives.asymmetric import ec, rsa

    if isinstance(key, ec.EllipticCurvePrivateKey):
        return "ecdsa-sha256"
    if isinstance(key, rsa.RSAPrivateKey):
        return "rsa-sha256"
    raise DccSigningError(
        f"--sign: the key is {type(key).__name__}; the DCC's XML signature needs an EC or RSA key"
    )


def sign_dcc(xml: bytes, signer: Any) -> bytes:
    """`xml` (a DCC) with the laboratory's enveloped XAdES-B signature as its root's last
    child, checked to verify before it is returned (DccSigningError if it would not)."""
    from lxml import etree
    from signxml.xades import XAdESSigner

    key, chain = _key_and_chain(signer)
    parser = etree.XMLParser(resolve_entities=False, no_network=True)
    root = etree.fromstring(xml, parser)
    xades = XAdESSigner(
        signature_algorithm=_algorithm(key), digest_algorithm="sha256", c14n_algorithm=_C14N_11
    )
    signed = xades.sign(root, key=key, cert=chain)
    out: bytes = etree.tostring(signed, xml_declaration=True, encoding="utf-8")
    status = check_dcc_signature(out)
    if not status.intact:
        raise DccSigningError(f"--sign: the signed DCC would not verify ({status.detail})")
    return out


@dataclass(frozen=True)
class DccSignature:
    """What a DCC's signature proves: whether there is one, whether it is intact over the
    whole DCC, its signer's certificate (DER), and whether the given CA trusts it (None: no
    CA given). `accelcal verify` words it (app.certificate.verify)."""

    signed: bool
    intact: bool
    detail: str = ""
    certificate_der: bytes = b""
    trusted: bool | None = None


def _signature_element(root: Any) -> Any:
    """The root's `ds:Signature` children (an enveloped signature is one of them)."""
    return root.findall(f"{{{DS_NS}}}Signature")


def check_dcc_signature(xml: bytes, roots: list[Any] | None = None) -> DccSignature:
    """Check the enveloped XAdES signature of the DCC `xml` (bytes as stored): exactly one
    `ds:Signature`, the root's child, whose reference covers the whole document and whose
    signature verifies with the certificate it carries (signxml); with `roots` (asn1crypto
    certificates: the lab's CA) also that the certificate chains to one of them now."""
    from lxml import etree

    try:
        root = etree.fromstring(
            xml, etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False)
        )
    except etree.XMLSyntaxError as exc:
        return DccSignature(True, False, f"not well-formed XML ({exc})")
    signatures = root.findall(f".//{{{DS_NS}}}Signature")
    if not signatures:
        return DccSignature(False, False, UNSIGNED_DETAIL)
    if len(signatures) != 1 or len(_signature_element(root)) != 1:
        return DccSignature(True, False, "not exactly one signature, the DCC root's child")
    certificate = _signing_certificate(signatures[0])
    if certificate is None:
        return DccSignature(True, False, "the signature carries no X.509 certificate")
    der = _der(certificate)
    problem = _verify(xml, certificate, None)
    if problem is not None:
        return DccSignature(True, False, problem, der)
    trusted = None
    if roots is not None:  # the signer is a given certificate itself, or chains to one
        pinned = any(root.dump() == der for root in roots)
        trusted = pinned or _verify(xml, certificate, roots) is None
    return DccSignature(True, True, "", der, trusted)


def _signing_certificate(signature: Any) -> Any:
    """The first X.509 certificate in the signature's KeyInfo (cryptography), or None."""
    from cryptography import x509

    node = signature.find(f"{{{DS_NS}}}KeyInfo/{{{DS_NS}}}X509Data/{{{DS_NS}}}X509Certificate")
    if node is None or not (node.text or "").strip():
        return None
    import base64

    try:
        return x509.load_der_x509_certificate(base64.b64decode("".join(node.text.split())))
    except ValueError:
        return None


def _der(certificate: Any) -> bytes:
    from cryptography.hazmat.primitives.serialization import Encoding

    der: bytes = certificate.public_bytes(Encoding.DER)
    return der


def _verify(xml: bytes, certificate: Any, roots: list[Any] | None) -> str | None:
    """None when signxml verifies the signature over the whole DCC (with `certificate`'s key;
    with `roots`, the chain the signature carries to one of them instead); else why not."""
    from signxml.exceptions import InvalidInput, InvalidSignature
    from signxml.xades import XAdESSignatureConfiguration, XAdESVerifier

    config = XAdESSignatureConfiguration(location="./")  # the root's child, nowhere else
    try:
        with _ca_file(roots) as ca:
            kwargs: dict[str, Any] = {"ca_pem_file": ca} if ca else {"x509_cert": certificate}
            results = XAdESVerifier().verify(xml, expect_config=config, **kwargs)
    except (InvalidSignature, InvalidInput) as exc:
        return f"the signature does not verify: {exc}"
    except Exception as exc:  # signxml and cryptography fail variously on a damaged signature
        return f"the signature cannot be checked: {exc}"
    whole = [r for r in results if r.signed_xml is not None and _is_root(r.signed_xml)]
    if not whole:
        return "the signature does not cover the whole DCC"
    return None


def _is_root(element: Any) -> bool:
    root = element.getparent() is None
    return bool(root and str(element.tag).endswith("}digitalCalibrationCertificate"))


@contextlib.contextmanager
def _ca_file(roots: list[Any] | None) -> Iterator[str | None]:
    """A temporary PEM file of `roots` (asn1crypto certificates) for signxml, or None."""
    if roots is None:
        yield None
        return
    from asn1crypto import pem

    with tempfile.NamedTemporaryFile(suffix=".pem") as handle:
        for root in roots:
            handle.write(pem.armor("CERTIFICATE", root.dump()))
        handle.flush()
        yield handle.name
