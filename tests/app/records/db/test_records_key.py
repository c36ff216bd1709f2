"""The records key (app.records.db.records_key) as a lab meets it through the CLI: `db upgrade`
makes it outside the database (mode 0600, its public half beside it) and says where; a write
without it is refused naming where it was looked for, nothing written; a password-protected key
needs its password; `db verify` checks the heads against the configured public key, not the one
the records hold."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest
from sqlalchemy import text

from app.cli import main
from app.records.db import chain_check, records_key
from app.records.db.engine import make_engine, resolve_url


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(list(argv))
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err


@pytest.fixture
def own_key(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """This test's records key location (nothing there yet)."""
    key = tmp_path / "keys" / "records-key.pem"
    monkeypatch.setenv(records_key.KEY_ENV, str(key))
    return key


def test_upgrade_makes_the_key_outside_the_database_and_every_head_is_signed(
    tmp_path: Path, own_key: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    url = f"sqlite:///{tmp_path / 'lab.sqlite'}"
    code, out, _ = _run(capsys, "db", "upgrade", "--db", url)
    assert code == 0 and f"records key: {own_key}" in out
    assert stat.S_IMODE(own_key.stat().st_mode) == 0o600
    assert own_key.with_suffix(".pub").read_bytes().startswith(b"-----BEGIN PUBLIC KEY-----")
    key = records_key.require_key()
    assert _run(capsys, "customers", "add", "ACME Ltd", "--db", url)[0] == 0
    engine = make_engine(resolve_url(url))
    with engine.connect() as c:
        pem = own_key.read_bytes()
        stored = " ".join(
            str(v) for row in c.execute(text("SELECT * FROM records_chain")) for v in row
        )
        assert pem.split(b"\n")[1].decode() not in stored  # the private key is not in the records
        head = c.execute(
            text("SELECT seq, hash, signature, key_id FROM records_chain ORDER BY seq DESC")
        ).first()
        keys = c.execute(text("SELECT key_id, public_key FROM records_keys")).all()
    engine.dispose()
    assert head is not None and head.key_id == key.key_id
    trusted = records_key.trusted_key()
    assert trusted is not None
    with engine.connect() as c:
        first = (chain_check._signed_before(c, head.seq) or 0) + 1
    assert first == head.seq  # one entry in that append
    assert trusted.verifies(first, head.seq, head.hash, head.signature)
    assert not trusted.verifies(first - 1, head.seq, head.hash, head.signature)
    assert keys == [(key.key_id, key.public_hex)]
    assert _run(capsys, "db", "verify", "--db", url)[0] == 0


def test_a_write_without_the_key_is_refused_and_nothing_is_written(
    tmp_path: Path, own_key: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    url = f"sqlite:///{tmp_path / 'lab.sqlite'}"
    assert _run(capsys, "db", "upgrade", "--db", url)[0] == 0
    monkeypatch.setenv(records_key.KEY_ENV, str(tmp_path / "elsewhere.pem"))
    code, _, err = _run(capsys, "customers", "add", "ACME Ltd", "--db", url)
    assert code == 2
    assert f"records key {tmp_path / 'elsewhere.pem'}: missing" in err
    monkeypatch.setenv(records_key.KEY_ENV, str(own_key))
    code, out, _ = _run(capsys, "customers", "list", "--db", url)
    assert code == 0 and "ACME" not in out
    assert _run(capsys, "db", "verify", "--db", url)[0] == 0


def test_a_password_protected_key_needs_its_password(
    tmp_path: Path, own_key: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.setenv(records_key.PASSWORD_ENV, "correct horse")
    url = f"sqlite:///{tmp_path / 'lab.sqlite'}"
    assert _run(capsys, "db", "upgrade", "--db", url)[0] == 0
    assert b"ENCRYPTED" in own_key.read_bytes()
    monkeypatch.setenv(records_key.PASSWORD_ENV, "wrong")
    code, _, err = _run(capsys, "customers", "add", "ACME Ltd", "--db", url)
    assert code == 2 and f"records key {own_key}: cannot load it" in err


def test_db_verify_trusts_the_configured_public_key_not_the_records(
    tmp_path: Path, own_key: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """Mallory's key replaces the lab's on this workstation and signs a write: the lab's
    public key, configured by --records-key or $ACCELCAL_RECORDS_PUBLIC_KEY, names it."""
    url = f"sqlite:///{tmp_path / 'lab.sqlite'}"
    assert _run(capsys, "db", "upgrade", "--db", url)[0] == 0
    lab_public = tmp_path / "lab.pub"
    lab_public.write_bytes(own_key.with_suffix(".pub").read_bytes())
    mallory = records_key.create_key(tmp_path / "mallory" / "records-key.pem")
    monkeypatch.setenv(records_key.KEY_ENV, str(mallory.path))
    assert _run(capsys, "customers", "add", "Shadow Corp", "--db", url)[0] == 0
    engine = make_engine(resolve_url(url))
    with engine.connect() as c:  # the records hold both keys: they cannot say which to trust
        held = set(c.execute(text("SELECT key_id FROM records_keys")).scalars())
    engine.dispose()
    assert mallory.key_id in held and len(held) == 2
    for argv, env in ((["--records-key", str(lab_public)], None), ([], str(lab_public))):
        if env:
            monkeypatch.setenv(records_key.PUBLIC_ENV, env)
        code, out, _ = _run(capsys, "db", "verify", "--db", url, *argv)
        assert code == 2
        assert f"signed by key {mallory.key_id[:16]}..., not the configured records key" in out
    monkeypatch.setenv(records_key.PUBLIC_ENV, str(tmp_path / "none.pub"))
    code, _, err = _run(capsys, "db", "verify", "--db", url)
    assert code == 2 and f"{tmp_path / 'none.pub'}: no such file" in err


def test_records_chained_before_0011_are_signed_by_the_upgrade(
    tmp_path: Path, own_key: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A lab at revision 0010 (its chain unsigned, its fingerprint the schema cookie) upgrades:
    the first signed head covers the whole chain before it, and db verify holds."""
    from app.records.db.engine import SCHEMA_HEAD, upgrade
    from app.records.db.lab import Lab

    url = resolve_url(f"sqlite:///{tmp_path / 'lab.sqlite'}")
    engine = make_engine(url)
    upgrade(engine, "0010")
    Lab(engine, actor="alice").add_customer("ACME Ltd")  # chained unsigned, as 0010 did
    with engine.connect() as c:
        assert c.execute(text("SELECT count(*) FROM records_chain")).scalar() > 1
    assert upgrade(engine) == ("0010", SCHEMA_HEAD)  # the head: 0014, after 0012 and 0013
    with engine.connect() as c:
        signed = c.execute(text("SELECT seq FROM records_chain WHERE signature IS NOT NULL"))
        last = c.execute(text("SELECT max(seq) FROM records_chain")).scalar()
    assert list(signed.scalars()) == [last]
    engine.dispose()
    assert _run(capsys, "db", "verify", "--db", url)[0] == 0
    assert _run(capsys, "customers", "add", "Other GmbH", "--db", url)[0] == 0
    assert _run(capsys, "db", "verify", "--db", url)[0] == 0
