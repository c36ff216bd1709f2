"""Shared runs and keys for the certificate tests (issue 31 point 6): each run is made once per
session and certified many times, so the matrix of issuing paths costs a few runs.

    pki            a throwaway lab CA and its signer key (tests/app/certificate/throwaway_ca.py)
    lab            a records database migrated once, the sensor SN-7 and the simulated stand's
                   reference standard REF-8305-SIM on record (the README's walkthrough)
    records_runs   two complete runs of SN-7 made by `accelcal run --sim --sensor SN-7 --db`
                   (their seals name the records chain head)
    plain_run      a complete run made without records (copy of the session's complete_run)
    run_100        a complete run of a 100-line plan (`accelcal run --frequencies`) of SN-100,
                   whose customer's name and address wrap over several lines, with records

Nothing here may be changed by a test but the certificates it adds (each test gives its own
--out, or a copy of the run's root).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from tests.app.certificate.throwaway_ca import PASSWORD, make_ca, make_signer

ROOT = Path(__file__).resolve().parents[3]
SENSOR = "SN-7"
CUSTOMER = "ACME Ltd"
LONG_SENSOR = "SN-100"  # a sensor of a customer whose name and address wrap over lines
LONG_CUSTOMER = " ".join(["Physikalisch-Technische Kalibrierlaboratorien Braunschweig"] * 3)
LONG_ADDRESS = "Bundesallee 100, 38116 Braunschweig, " + "Gebäude " * 12 + "Raum 1"


@dataclass(frozen=True)
class Pki:
    """The lab's CA certificate (PEM) and a signer key it issued (PKCS#12, PASSWORD)."""

    ca: Path
    key: Path


@dataclass(frozen=True)
class Lab:
    """A records database (URL) with SN-7 and REF-8305-SIM on record, and its runs root."""

    url: str
    runs: Path


@pytest.fixture(scope="session")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    folder = tmp_path_factory.mktemp("pki")
    ca = make_ca(folder, "Test Lab CA")
    return Pki(ca.pem, make_signer(folder, "lab.p12", ca))


@pytest.fixture()
def sign_password(monkeypatch: pytest.MonkeyPatch) -> str:
    monkeypatch.setenv("ACCELCAL_SIGN_PASSWORD", PASSWORD)
    return PASSWORD


def _cli(*argv: str | Path) -> None:
    code = main([str(a) for a in argv])
    assert code == 0, argv


@pytest.fixture(scope="session")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Lab:
    """The README's records walkthrough, by the CLI: schema, customer, model, sensor, and the
    simulated stand's reference standard with a calibration table and a due date ahead."""
    base = tmp_path_factory.mktemp("lab")
    url = f"sqlite:///{base / 'records.sqlite'}"
    today = datetime.now(UTC).date()
    _cli("db", "upgrade", "--db", url)
    _cli("customers", "add", CUSTOMER, "--address", "1 Test Street, 00-001 Testtown", "--db", url)
    _cli("models", "add", "PCB", "352C33", "--nominal", "100", "--unit", "mV/g",
         "--tolerance", "5", "--fmin", "1", "--fmax", "10000", "--db", url)  # fmt: skip
    _cli("sensors", "add", SENSOR, "--model", "352C33", "--owner", CUSTOMER, "--db", url)
    _cli("customers", "add", LONG_CUSTOMER, "--address", LONG_ADDRESS, "--db", url)
    _cli("sensors", "add", LONG_SENSOR, "--model", "352C33", "--owner", LONG_CUSTOMER,
         "--db", url)  # fmt: skip
    _cli("refs", "add", "REF-8305-SIM", "--model", "B&K 8305", "--serial", "SIM-0001",
         "--certificate", "PTB-1", "--calibrated", str(today - timedelta(days=30)),
         "--due", str(today + timedelta(days=300)), "--table", ROOT / "examples/ref-table.csv",
         "--db", url)  # fmt: skip
    return Lab(url, base / "runs")


def _new_run(out: Path, *argv: str | Path) -> Path:
    before = set(out.iterdir()) if out.exists() else set()
    _cli("run", "--sim", "--periods", "3", "--out", out, *argv)
    (folder,) = set(out.iterdir()) - before
    return folder


@pytest.fixture(scope="session")
def records_runs(lab: Lab) -> tuple[Path, Path]:
    """Two complete runs of SN-7 with the records in use (indexed when they end)."""
    return tuple(  # type: ignore[return-value]
        _new_run(lab.runs, "--sensor", SENSOR, "--seed", str(seed), "--db", lab.url)
        for seed in (1, 2)
    )


@pytest.fixture(scope="session")
def run_100(lab: Lab) -> Path:
    """100 lines, 20 Hz to 2.5 kHz (geometric on the piezo plan's 0.5 Hz bins, 160 Hz among
    them) at 2 m/s^2, of SN-100 (the long-named customer's) with the records in use; no
    technician named."""
    lines = np.unique(np.append(np.round(np.geomspace(20, 2500, 99) * 2) / 2, 160.0))
    assert len(lines) == 100
    frequencies = ",".join(f"{f:g}" for f in lines)
    return _new_run(lab.runs, "--sensor", LONG_SENSOR, "--db", lab.url, "--level", "2",
                    "--frequencies", frequencies, "--seed", "5")  # fmt: skip


def copy_run(run: Path, root: Path) -> Path:
    """`run` copied into the runs root `root` (its own JSON register), certificates left out."""
    copy = root / run.name
    shutil.copytree(run, copy, ignore=shutil.ignore_patterns("certificate*"))
    return copy
