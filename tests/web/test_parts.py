"""The web view's parts on their own: the read-only engine, the document checks, staff users,
the QR code of a verification address, the chart's ticks and the server's options."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest
from sqlalchemy import select, text
from sqlalchemy.exc import DBAPIError, OperationalError

from app.certificate.qr import QrError, check_verify_url, qr_png, verification_code, verify_address
from app.records.db.engine import (
    SCHEMA_HEAD,
    DatabaseError,
    make_engine,
    resolve_url,
    upgrade,
)
from app.records.db.lab import RecordsError
from app.records.db.models import AuditEntry, Certificate, User
from app.records.run_folder import sha256_of
from app.web.__main__ import main as web_main
from app.web.chart import nice_ticks
from app.web.documents import (
    DocumentError,
    certificate_dcc,
    certificate_pdf,
    certificate_pdf_bytes,
)
from app.web.store import open_read_only
from app.web.users import add_user, password_matches
from tests.pg_server import start_pgserver
from tests.records_db import new_records
from tests.web.conftest import Records

MANIFEST = "ab" * 32


def test_the_verification_code_is_80_bits_of_hmac_keyed_by_the_manifest() -> None:
    # computed with openssl: echo -n ACC-2026-0001 | openssl dgst -sha256 -mac HMAC
    # -macopt hexkey:abab...ab (32 bytes), first 10 bytes of the MAC | base32
    assert verification_code("ACC-2026-0001", MANIFEST) == "hxu7fydcdk432n44"
    assert len(verification_code("ACC-2026-0001", MANIFEST)) == 16
    assert verification_code("ACC-2026-0001", MANIFEST.upper()) == verification_code(
        "ACC-2026-0001", MANIFEST
    )
    assert verification_code("ACC-2026-0002", MANIFEST) != verification_code(
        "ACC-2026-0001", MANIFEST
    )
    assert verification_code("ACC-2026-0001", "cd" * 32) != verification_code(
        "ACC-2026-0001", MANIFEST
    )


def test_a_verification_address_appends_the_escaped_number_and_the_code() -> None:
    code = verification_code("ACC 1/2", MANIFEST)
    assert verify_address("https://lab.example/verify/", "ACC 1/2", MANIFEST) == (
        f"https://lab.example/verify/ACC%201%2F2?code={code}"
    )


@pytest.mark.parametrize(
    "url",
    ["lab.example/verify", "ftp://lab.example/v", "https://", "https://lab/v?x=1", "http://l/#a"],
)
def test_a_verify_url_that_cannot_take_a_number_is_refused(url: str) -> None:
    with pytest.raises(QrError, match=r"laboratory\.verify_url"):
        check_verify_url(url)


def test_a_manifest_hash_that_is_no_sha256_is_refused() -> None:
    with pytest.raises(QrError, match="manifest hash"):
        verification_code("ACC-2026-0001", "abc")


def test_the_qr_png_decodes_to_the_address() -> None:
    import io

    import zxingcpp
    from PIL import Image

    address = verify_address("https://lab.example/verify", "ACC-2026-0007", MANIFEST)
    (found,) = zxingcpp.read_barcodes(Image.open(io.BytesIO(qr_png(address))))
    assert found.text == address


@pytest.mark.parametrize(
    ("low", "high", "expected"),
    [(0.0, 10.0, [0, 2, 4, 6, 8, 10]), (9.93, 10.41, [10.0, 10.1, 10.2, 10.3, 10.4])],
)
def test_chart_ticks_are_round_numbers_within_the_range(low, high, expected) -> None:
    assert nice_ticks(low, high) == pytest.approx(expected)


def _migrated(tmp_path: Path, revision: str = "head") -> str:
    if revision == "head":  # a copy of the database migrated once per process
        return resolve_url(new_records(tmp_path / "r.sqlite"))
    url = resolve_url(f"sqlite:///{tmp_path / 'r.sqlite'}")
    engine = make_engine(url)
    upgrade(engine, revision)
    engine.dispose()
    return url


@pytest.mark.integration
def test_the_web_views_engine_cannot_write(tmp_path: Path) -> None:
    engine = open_read_only(_migrated(tmp_path))
    with pytest.raises(OperationalError, match="readonly"), engine.begin() as conn:
        conn.execute(text("INSERT INTO settings (key, value) VALUES ('x', 'y')"))


@pytest.mark.integration
def test_the_web_view_refuses_a_missing_or_old_database(tmp_path: Path) -> None:
    with pytest.raises(DatabaseError, match="no records database"):
        open_read_only(f"sqlite:///{tmp_path / 'none.sqlite'}")
    assert not (tmp_path / "none.sqlite").exists()  # not created either
    with pytest.raises(
        DatabaseError, match=f"schema revision 0005, this program needs {SCHEMA_HEAD}"
    ):
        open_read_only(_migrated(tmp_path, "0005"))


@pytest.mark.integration
def test_a_user_is_stored_with_an_argon2_hash_and_audited_without_it(tmp_path: Path) -> None:
    engine = make_engine(_migrated(tmp_path))
    add_user(engine, "tech.1", "twelve chars!", display_name="A Technician", actor="admin")
    with engine.connect() as conn:
        user = conn.execute(select(User)).one()
        audit = conn.execute(select(AuditEntry).where(AuditEntry.table_name == "users")).one()
    assert user.password_hash.startswith("$argon2id$")
    assert password_matches(user.password_hash, "twelve chars!")
    assert not password_matches(user.password_hash, "twelve chars?")
    assert not password_matches("not a hash", "twelve chars!")
    changes = json.loads(audit.changes)
    assert audit.actor == "admin" and audit.row_key == "tech.1" and audit.action == "insert"
    assert changes["display_name"] == "A Technician"
    assert "argon2" not in audit.changes and changes["password_hash"] == "(not recorded)"


@pytest.mark.integration
@pytest.mark.parametrize(
    ("username", "password", "name", "field"),
    [
        ("a b", "twelve chars!", "X", "username"),
        ("x", "twelve chars!", "X", "username"),
        ("tech", "eleven char", "X", "password"),
        ("tech", "twelve chars!", "  ", "display name"),
        ("dup", "twelve chars!", "X", "username: 'dup' already exists"),
    ],
)
def test_a_bad_user_is_refused_by_field(tmp_path: Path, username, password, name, field) -> None:
    engine = make_engine(_migrated(tmp_path))
    add_user(engine, "dup", "twelve chars!", display_name="First")
    with pytest.raises(RecordsError, match=f"^{field}"):
        add_user(engine, username, password, display_name=name)
    with engine.connect() as conn:
        assert conn.execute(text("SELECT count(*) FROM users")).scalar() == 1


def _issued_copy(records: Records, tmp_path: Path) -> tuple[str, Path, str, str]:
    """The first certificate's register row (number, a copy of its PDF under tmp_path, the
    PDF's and the DCC's SHA-256 as recorded)."""
    number = records.numbers[0]
    with records.engine.connect() as conn:
        file, sha256, dcc_sha256 = conn.execute(
            select(Certificate.file, Certificate.sha256, Certificate.dcc_sha256).where(
                Certificate.number == number
            )
        ).one()
    assert file and sha256 and dcc_sha256
    pdf = tmp_path / "copy.pdf"
    shutil.copyfile(file, pdf)
    return number, pdf, sha256, dcc_sha256


@pytest.mark.integration
def test_only_the_registered_unchanged_pdf_is_served(records: Records, tmp_path: Path) -> None:
    number, pdf, sha256, dcc_sha256 = _issued_copy(records, tmp_path)
    assert sha256_of(pdf) == sha256
    assert certificate_pdf(number, str(pdf), sha256) == pdf
    assert certificate_pdf_bytes(number, str(pdf), sha256) == pdf.read_bytes()
    dcc = certificate_dcc(number, pdf, dcc_sha256)
    assert hashlib.sha256(dcc).hexdigest() == dcc_sha256 and dcc.startswith(b"<?xml")
    with pytest.raises(DocumentError, match="not the one issued"):
        certificate_dcc(number, pdf, "0" * 64)
    with pytest.raises(DocumentError, match="records no DCC"):
        certificate_dcc(number, pdf, None)
    for file, digest in ((None, sha256), (str(pdf), None)):  # a row from before 0009
        with pytest.raises(DocumentError, match="records no issued PDF"):
            certificate_pdf(number, file, digest)
    with pytest.raises(DocumentError, match="is missing"):  # relative: not the issued file
        certificate_pdf(number, pdf.name, sha256)
    pdf.chmod(0o644)
    with pdf.open("ab") as handle:
        handle.write(b"%% appended\n")
    for read in (certificate_pdf, certificate_pdf_bytes):
        with pytest.raises(DocumentError, match="changed since it was issued"):
            read(number, str(pdf), sha256)
    fake = tmp_path / "fake.pdf"
    fake.write_text("secret text, not a PDF")
    with pytest.raises(DocumentError, match="is not a PDF"):
        certificate_pdf(number, str(fake), sha256_of(fake))
    with pytest.raises(DocumentError, match="is missing"):
        certificate_pdf(number, str(tmp_path / "gone.pdf"), sha256)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--port", "0"], "--port: must be 1 to 65535"),
        (["--verify-url", "lab/verify"], "laboratory.verify_url"),
        (["--db", "mysql://x/y"], "--db: unsupported database"),
        (["--trust", "/nonexistent/ca.pem"], "--trust: no such file"),
    ],
)
def test_bad_server_options_exit_2_with_one_line(capsys, argv, message) -> None:
    assert web_main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.integration
def test_a_missing_database_exits_2(capsys, tmp_path: Path) -> None:
    assert web_main(["--db", f"sqlite:///{tmp_path / 'x.sqlite'}"]) == 2
    assert "no records database" in capsys.readouterr().err


def test_the_secret_must_be_long_enough(capsys, monkeypatch) -> None:
    monkeypatch.setenv("ACCELCAL_WEB_SECRET", "short")
    assert web_main(["--db", "sqlite:////nonexistent/x.sqlite"]) == 2
    assert "ACCELCAL_WEB_SECRET: shorter than 32" in capsys.readouterr().err


def test_the_history_chart_places_each_point_inside_the_frame_with_its_u_bar() -> None:
    import re
    from datetime import UTC, datetime

    from app.records.db.lab import History, HistoryPoint
    from app.web.chart import HEIGHT, LEFT, RIGHT, TOP, WIDTH, history_svg

    points = (
        HistoryPoint("r1", datetime(2025, 1, 1, tzinfo=UTC), 160.0, 10.0, 0.1),
        HistoryPoint("r2", datetime(2026, 1, 1, tzinfo=UTC), 160.0, 10.2, 0.1),
    )
    svg = history_svg(History("SN-1", points, 2.0))
    xs = [float(v) for v in re.findall(r'<circle cx="([\d.]+)"', svg)]
    ys = [float(v) for v in re.findall(r'<circle cx="[\d.]+" cy="([\d.]+)"', svg)]
    assert len(xs) == 2 and LEFT < xs[0] < xs[1] < WIDTH - RIGHT
    assert TOP < ys[1] < ys[0] < HEIGHT  # the higher sensitivity is drawn higher
    # the U bar of r1 spans 9.9..10.1: half as tall as the span 10.0..10.2 between the points
    bar = re.search(rf'x1="{xs[0]:.1f}" x2="{xs[0]:.1f}" y1="([\d.]+)" y2="([\d.]+)"', svg)
    assert bar is not None
    assert float(bar.group(1)) - float(bar.group(2)) == pytest.approx(ys[0] - ys[1], abs=0.2)
    assert "drift +2.000 % per year" in svg and "2025-01-01" in svg and "2026-01-01" in svg
    assert "no calibrations on record" in history_svg(History("SN-2", (), None))


@pytest.mark.integration
def test_on_postgresql_the_web_views_engine_cannot_write() -> None:
    import os
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="accelcal-web-pg-"))  # short: the socket lives here
    try:
        server = start_pgserver(folder)
    except Exception as exc:  # no wheel, no start
        shutil.rmtree(folder, ignore_errors=True)
        if os.environ.get("CI") == "true":
            pytest.fail(f"PostgreSQL could not start in CI: {exc}")
        pytest.skip(f"PostgreSQL could not start: {exc}")
    try:
        url = resolve_url(server.get_uri())
        writer = make_engine(url)
        upgrade(writer)
        add_user(writer, "pg.user", "twelve chars!", display_name="PG")
        writer.dispose()
        engine = open_read_only(url)
        from app.web.store import Store

        assert Store(engine).user("pg.user") is not None  # reads work
        with pytest.raises(DBAPIError, match="read-only transaction"), engine.begin() as conn:
            conn.execute(text("INSERT INTO settings (key, value) VALUES ('x', 'y')"))
        engine.dispose()
    finally:
        server.cleanup()
        shutil.rmtree(folder, ignore_errors=True)
