"""Writes signed.xml (lists_mv_degree.xml with an enveloped XML signature, signxml) and
signer.pem (the self-signed certificate of a key made here and thrown away), and other.pem (a
certificate of another key: a signature checked against it must fail). Run once from this
folder: `../../../.venv/bin/python make_signed.py`; the outputs are committed, the keys never."""

from __future__ import annotations

import datetime
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import rsa
from cryptography.x509.oid import NameOID
from lxml import etree
from signxml import XMLSigner, methods

HERE = Path(__file__).parent


def certificate(common_name: str) -> tuple[rsa.RSAPrivateKey, x509.Certificate]:
    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    name = x509.Name(
        [
            x509.NameAttribute(NameOID.COMMON_NAME, common_name),
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "National Vibration Laboratory"),
        ]
    )
    now = datetime.datetime(2026, 1, 1, tzinfo=datetime.UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now)
        .not_valid_after(now + datetime.timedelta(days=3650))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(True, True, False, False, False, False, False, False, False),
            critical=True,
        )
        .sign(key, hashes.SHA256())
    )
    return key, cert


def main() -> None:
    key, cert = certificate("DCC signing, National Vibration Laboratory")
    _, other = certificate("Someone else")
    pem = cert.public_bytes(serialization.Encoding.PEM)
    root = etree.parse(str(HERE / "lists_mv_degree.xml")).getroot()
    signed = XMLSigner(
        method=methods.enveloped, c14n_algorithm="http://www.w3.org/2001/10/xml-exc-c14n#"
    ).sign(root, key=key, cert=pem.decode())
    text = etree.tostring(signed, xml_declaration=True, encoding="UTF-8")
    (HERE / "signed.xml").write_bytes(text)
    (HERE / "signer.pem").write_bytes(pem)
    (HERE / "other.pem").write_bytes(other.public_bytes(serialization.Encoding.PEM))


if __name__ == "__main__":
    main()
