"""A throwaway PKI for signing tests (cryptography): a lab CA, another CA, and PKCS#12 signer
keys issued by either, self-signed, expired or not yet valid."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.hazmat.primitives.serialization import pkcs12
from cryptography.x509.oid import NameOID

PASSWORD = "correct horse"
LAB_SIGNER = "Vibration Calibration Laboratory"


def name(common: str) -> x509.Name:
    """An X.509 name with only a common name."""
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common)])


@dataclass(frozen=True)
class Authority:
    """A CA: its key, its certificate and where its PEM was written."""

    key: ec.EllipticCurvePrivateKey
    cert: x509.Certificate
    pem: Path


def make_ca(folder: Path, common: str) -> Authority:
    """A self-signed CA valid from yesterday for 30 days, its PEM written to `folder`."""
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(name(common))
        .issuer_name(name(common))
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(days=1))
        .not_valid_after(now + dt.timedelta(days=30))
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(False, False, False, False, False, True, True, False, False),
            critical=True,
        )
        .sign(key, hashes.SHA256())
    )
    pem = folder / f"{common.replace(' ', '-')}.pem"
    pem.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return Authority(key, cert, pem)


def make_signer(
    folder: Path,
    file_name: str,
    issuer: Authority | None,
    common: str = LAB_SIGNER,
    valid_from_days: float = -1,
    valid_to_days: float = 30,
) -> Path:
    """A PKCS#12 signer key (password PASSWORD) issued by `issuer`, or self-signed when None,
    valid from/to the given days relative to now; its path."""
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    builder = (
        x509.CertificateBuilder()
        .subject_name(name(common))
        .issuer_name(issuer.cert.subject if issuer else name(common))
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now + dt.timedelta(days=valid_from_days))
        .not_valid_after(now + dt.timedelta(days=valid_to_days))
        .add_extension(
            x509.KeyUsage(True, True, False, False, False, False, False, False, False),
            critical=True,
        )
    )
    cert = builder.sign(issuer.key if issuer else key, hashes.SHA256())
    chain = [issuer.cert] if issuer else None
    path = folder / file_name
    path.write_bytes(
        pkcs12.serialize_key_and_certificates(
            b"signer",
            key,
            cert,
            chain,
            serialization.BestAvailableEncryption(PASSWORD.encode()),
        )
    )
    return path
