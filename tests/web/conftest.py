"""A records database with real certificates for the web view's tests: two simulated runs of
sensor SN-WEB-1 indexed, certificate 1 issued and then amended by certificate 2 (of the second
run), certificate 3 withdrawn; a staff user; and the web app over it."""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.hazmat.primitives.serialization import pkcs12
from cryptography.x509.oid import NameOID
from sqlalchemy import Engine

from app.certificate import CertificateInfo
from app.certificate.register_issue import issue_registered
from app.certificate.sign import Signer
from app.cli import main
from app.records.db.engine import make_engine, resolve_url
from app.records.db.lab import Lab
from app.web.users import add_user
from tests.records_db import new_records

USER, PASSWORD = "qm", "correct horse battery"
SERIAL = "SN-WEB-1"


@dataclass(frozen=True)
class Records:
    """The test records: URL, engine, run folders and certificate numbers (old to new)."""

    url: str
    engine: Engine
    runs: tuple[Path, ...]
    numbers: tuple[str, ...]
    lab_certificate: Path  # PEM: the self-signed certificate the valid one is signed with


def _lab_key(folder: Path) -> tuple[Path, Path]:
    """A throwaway self-signed lab key and certificate: (PKCS#12 file, PEM certificate)."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "Web Test Laboratory")])
    now = datetime.now(UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - timedelta(days=1))
        .not_valid_after(now + timedelta(days=30))
        .sign(key, hashes.SHA256())
    )
    p12, pem = folder / "lab.p12", folder / "lab.pem"
    p12.write_bytes(
        pkcs12.serialize_key_and_certificates(
            b"lab", key, cert, None, serialization.BestAvailableEncryption(b"secret")
        )
    )
    pem.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return p12, pem


def _run(out: Path, seed: int) -> Path:
    before = set(out.iterdir()) if out.exists() else set()
    argv = ["run", "--sim", "--dut", "piezo", "--dut-id", SERIAL, "--periods", "3"]
    assert main([*argv, "--seed", str(seed), "--out", str(out)]) == 0
    (folder,) = set(out.iterdir()) - before
    return folder


@pytest.fixture(scope="package")
def records(tmp_path_factory: pytest.TempPathFactory) -> Records:
    base = tmp_path_factory.mktemp("web")
    runs_root = base / "runs"
    url = resolve_url(new_records(base / "records.sqlite"))
    engine = make_engine(url)
    lab = Lab(engine, actor="test")
    lab.add_customer("ACME Ltd", "1 Test Street, Testville")
    lab.add_customer("Other GmbH")
    lab.add_model(
        "Sim",
        "P-100",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5.0,
        frequency_min_hz=10.0,
        frequency_max_hz=10000.0,
    )
    lab.add_sensor(SERIAL, model="P-100", owner="ACME Ltd")
    lab.add_sensor("SN-WEB-2", model="P-100", owner="Other GmbH")
    runs = (_run(runs_root, 3), _run(runs_root, 4))
    info = CertificateInfo(
        authorised_by="J. Smith",
        dut_type="piezoelectric accelerometer",
        temperature_c=23.0,
        mounting="stud-mounted",
    )
    p12, pem = _lab_key(base)
    signer = Signer.load(p12, "secret")
    numbers = []
    # the third: run 0 again once its certificate is replaced (one in force per run, issue 24)
    for index, (run, replaces) in enumerate(((runs[0], None), (runs[1], "first"), (runs[0], None))):
        issued = issue_registered(
            run,
            info,
            base / f"certificate-{index}.pdf",
            url=url,
            prepared_by="A. Preparer",
            replaces=numbers[0] if replaces else None,
            reason="typing error in the mounting" if replaces else None,
            signer=signer if index == 1 else None,  # the valid one is signed
        )
        numbers.append(issued.number)
    lab.withdraw_certificate(numbers[2], "issued twice")
    add_user(engine, USER, PASSWORD, display_name="Quality Manager", actor="test")
    return Records(url, engine, runs, tuple(numbers), pem)


@pytest.fixture(scope="package")
def store(records: Records):
    """The web view's read-only access to the test records."""
    from app.web.store import Store, open_read_only

    engine = open_read_only(records.url)
    yield Store(engine)
    engine.dispose()


@pytest.fixture
def web_app(store, records):
    """A fresh web app (its own sign-in throttle) over the test records."""
    from app.web.server import WebConfig, create_app

    config = WebConfig(
        secret_key="k" * 40, verify_url="https://lab.example/verify", trust=records.lab_certificate
    )
    return create_app(store, config)


# ---- the customer portal (issue 35 point 5) ---------------------------------------------
ACME_ACCOUNT, OTHER_ACCOUNT = "acme.buyer", "other.buyer"
ACME_PASSWORD, OTHER_PASSWORD = "acme portal password", "other portal password"
NEVER_CALIBRATED = "SN-WEB-3"  # ACME's, no run: no due date


@dataclass(frozen=True)
class PortalRecords:
    """Records of two customers, each with one issued certificate: ACME Ltd (sensor
    SN-WEB-1, certificate `acme`; SN-WEB-3 never calibrated) and Other GmbH (SN-WEB-2,
    certificate `other`), an account of each and a staff user."""

    url: str
    engine: Engine
    acme: str
    other: str
    acme_pdf: Path
    other_pdf: Path


@pytest.fixture(scope="package")
def portal_records(tmp_path_factory: pytest.TempPathFactory, records: Records) -> PortalRecords:
    from app.web.accounts import add_account

    base = tmp_path_factory.mktemp("portal")
    url = resolve_url(new_records(base / "records.sqlite"))
    engine = make_engine(url)
    lab = Lab(engine, actor="test")
    lab.add_customer("ACME Ltd", "1 Test Street, Testville")
    lab.add_customer("Other GmbH", "2 Other Street, Elsewhere")
    lab.add_model(
        "Sim",
        "P-100",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5.0,
        frequency_min_hz=10.0,
        frequency_max_hz=10000.0,
    )
    lab.add_sensor(SERIAL, model="P-100", owner="ACME Ltd")
    lab.add_sensor("SN-WEB-2", model="P-100", owner="Other GmbH")
    lab.add_sensor(NEVER_CALIBRATED, model="P-100", owner="ACME Ltd")
    runs_root = base / "runs"
    argv = ["run", "--sim", "--dut", "piezo", "--dut-id", "SN-WEB-2", "--periods", "3"]
    assert main([*argv, "--seed", "5", "--out", str(runs_root)]) == 0
    (other_run,) = runs_root.iterdir()
    info = CertificateInfo(
        authorised_by="J. Smith",
        dut_type="piezoelectric accelerometer",
        temperature_c=23.0,
        mounting="stud-mounted",
    )
    acme_run = base / "acme-runs" / records.runs[0].name  # a copy: the staff tests' stays as it is
    shutil.copytree(records.runs[0], acme_run)
    numbers, pdfs = [], []
    for index, run in enumerate((acme_run, other_run)):
        pdf = base / f"portal-{index}.pdf"
        issued = issue_registered(run, info, pdf, url=url, prepared_by="A. Preparer")
        numbers.append(issued.number)
        pdfs.append(pdf)
    add_account(engine, ACME_ACCOUNT, ACME_PASSWORD, customer="ACME Ltd",
                display_name="ACME purchasing", actor="test")  # fmt: skip
    add_account(engine, OTHER_ACCOUNT, OTHER_PASSWORD, customer="Other GmbH",
                display_name="Other purchasing", actor="test")  # fmt: skip
    add_user(engine, USER, PASSWORD, display_name="Quality Manager", actor="test")
    return PortalRecords(url, engine, numbers[0], numbers[1], pdfs[0], pdfs[1])


@pytest.fixture(scope="package")
def portal_store(portal_records: PortalRecords):
    """The web view's read-only access to the portal's records."""
    from app.web.store import Store, open_read_only

    engine = open_read_only(portal_records.url)
    yield Store(engine)
    engine.dispose()


PORTAL_SECRET = "p" * 8 + "ortal-secret-0123456789abcdefghij"


@pytest.fixture
def portal_app(portal_store):
    """A fresh web app (its own throttles and sessions) over the portal's records."""
    from app.web.server import WebConfig, create_app

    return create_app(portal_store, WebConfig(secret_key=PORTAL_SECRET))
