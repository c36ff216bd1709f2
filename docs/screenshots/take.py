"""Screenshots of every tab: a records database with two customers' sensors, their history,
run templates and a certificate register (issued, amended, withdrawn), one simulated run of a
registered sensor from its template, its certificate issued through the register, each tab
grabbed, and the certificate dialog of that run; then four registered sensors in one run on the
simulated four-position fixture with its physics (sim/stand-fixture4-physics.toml, issue 36:
the off-axis positions' rocking shows in their deviations at the top lines): its Setup, Run and Results
tabs grabbed as 8-batch-setup, 9-batch-run and 10-batch-results.

    xvfb-run -s "-screen 0 1920x1080x24" env QT_QPA_PLATFORM=xcb \
        python docs/screenshots/take.py [WIDTHxHEIGHT]        # default 1366x768
    QT_QPA_PLATFORM=offscreen python docs/screenshots/take.py [WIDTHxHEIGHT]
"""

from __future__ import annotations

import os
import sys
import tempfile
from datetime import UTC, date, datetime
from pathlib import Path
from typing import Any

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import QCoreApplication, QEventLoop, QTimer
from PySide6.QtWidgets import QApplication

from app.certificate import CertificateInfo
from app.certificate.register_issue import issue_registered
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.records.db.models import Run, Stand
from app.web.users import add_user

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
BATCH = {"A": "SN-2101", "B": "SN-2102", "C": "SN-2103", "D": "SN-2104"}  # position: serial


def records(url: str) -> None:
    lab = Lab(open_engine(url, create=True), actor="screenshots")
    lab.add_customer("ACME Ltd", "1 Main Street, Springfield")
    lab.add_customer("Vibration Labs GmbH")
    lab.add_model(
        "PCB",
        "352C33",
        nominal_sensitivity=100.0,
        unit="mV/g",
        tolerance_percent=5,
        frequency_min_hz=1,
        frequency_max_hz=10000,
        level_ms2=5.0,
    )
    lab.add_model(
        "Brüel & Kjær",
        "4533-B",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=3,
        frequency_min_hz=1,
        frequency_max_hz=10000,
        level_ms2=5.0,
    )
    lab.add_sensor("SN-1042", model="352C33", owner="ACME Ltd")
    lab.add_sensor("SN-1043", model="352C33", owner="ACME Ltd", interval_months=24)
    lab.add_sensor("BK-2210", model="4533-B", owner="Vibration Labs GmbH")
    for serial in BATCH.values():  # a customer's batch of one model, four at a time
        lab.add_sensor(serial, model="352C33", owner="ACME Ltd")
    history = [
        ("SN-1042", date(2022, 11, 2), 10.22, 0.06),
        ("SN-1042", date(2023, 11, 6), 10.25, 0.06),
        ("SN-1042", date(2024, 11, 4), 10.27, 0.05),
        ("SN-1042", date(2025, 11, 3), 10.31, 0.05),
        ("BK-2210", date(2024, 6, 12), 9.98, 0.04),
    ]
    lab.add_template(
        "352C33",
        "5 lines, quick",
        preset="piezo",
        frequencies_hz=[40, 80, 160, 315, 630],
        level_ms2=5.0,
        periods=4,
        estimator="periodic",
    )
    lab.add_template(
        "352C33",
        "full, 0.2 % type A",
        preset="piezo",
        level_ms2=5.0,
        periods=8,
        target_type_a=0.002,
        max_acquisition_s=30.0,
        estimator="periodic",
    )
    # the two-person rule's persons: users of the records (`accelcal records user add`)
    for username, name in (("atech", "A. Tech"), ("jsmith", "J. Smith")):
        add_user(lab.engine, username, "screenshots only", display_name=name, actor="screenshots")
    lab.set_setting("two_person_rule", "on")
    ids = {s.serial: s.id for s in lab.sensors()}
    with lab.session() as session:
        stand = Stand(stand_file_sha256="0" * 64, name="simulated stand")
        for n, (serial, day, s, u) in enumerate(history):
            session.add(
                Run(
                    run_id=f"hist-{n}",
                    manifest_sha256=f"{n}".rjust(64, "0"),
                    folder=f"/runs/hist-{n}",
                    status="complete",
                    started_utc=datetime(day.year, day.month, day.day, 9, tzinfo=UTC),
                    dut_id=serial,
                    stand=stand,
                    sensor_id=ids[serial],
                    reference_frequency_hz=160.0,
                    sensitivity_mv_per_ms2=s,
                    expanded_uncertainty_mv_per_ms2=u,
                )
            )
    for n, (_serial, day, _s, _u) in enumerate(history):
        when = datetime(day.year, day.month, day.day, 15, tzinfo=UTC)
        lab.issue_certificate(
            run_id=f"hist-{n}", prepared_by="A. Tech", approved_by="J. Smith", when=when
        )
    first = lab.register()[0].number
    lab.issue_certificate(
        run_id="hist-0",
        prepared_by="A. Tech",
        approved_by="J. Smith",
        when=datetime(2022, 11, 9, 10, tzinfo=UTC),
        replaces=first,
        reason="customer address corrected",
    )
    lab.withdraw_certificate(lab.register()[2].number, "wrong sensor mounted")


def certificate_dialog(window: Any, folder: Path, width: int, height: int) -> Path:
    """The certificate dialog of the run in `folder` as the Certificate action opens it (the
    customer and sensor from the records), grabbed and closed unanswered."""
    from app.gui.certificate_dialog import CertificateDialog
    from app.records.run_folder import load_run

    record = load_run(folder)
    dialog = CertificateDialog(
        window,
        record,
        dict(window.records.certificate_defaults(record)),
        prepared_by="A. Tech",
        heading="Certificate",
    )
    dialog.show()
    for _ in range(5):
        QCoreApplication.processEvents()
    path = HERE / f"7-certificate-{width}x{height}.png"
    dialog.grab().save(str(path))
    dialog.reject()
    return path


def run_and_wait(window: Any, count: int) -> None:
    """Start the run the Setup tab describes once it may, and wait for its `count` members'
    ends (1: a single run)."""
    loop = QEventLoop()
    ended: list[Any] = []

    def one(finished: Any) -> None:
        ended.append(finished)
        if len(ended) == count:
            QTimer.singleShot(300, loop.quit)

    window.run_finished.connect(one)
    while not window.setup_tab.start_button.isEnabled():
        QCoreApplication.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 50)
    window.start_run()
    loop.exec()
    window.records.wait_jobs()


def batch_shots(work: Path, url: str, width: int, height: int) -> list[Path]:
    """Four DUTs in one run on the simulated fixture: the Setup tab with their serials (looked
    up in the records), the Run tab with each one's deviation, the Results tab with a verdict
    per DUT, grabbed after the run."""
    from app.gui.main_window import MainWindow

    window = MainWindow(
        stand_file=ROOT / "sim" / "stand-fixture4-physics.toml",
        out=work / "batch-runs",
        paced=False,
        seed=4,
        db=url,
    )
    window.setGeometry(0, 0, width, height)
    window.show()
    window.records.wait()
    setup = window.setup_tab
    setup.technician.setText("A. Tech")
    rows = {row.position.name: row for row in setup.fixture.rows}
    for position, serial in BATCH.items():
        rows[position].serial.setText(serial)
        rows[position].serial.editingFinished.emit()
    window.wait_for_plans()  # the piezo preset's 25 lines, 10 Hz to 2.5 kHz
    shots = []
    for index, name in ((0, "8-batch-setup"),):
        window.tabs.setCurrentIndex(index)
        for _ in range(5):
            QCoreApplication.processEvents()
        shots.append(HERE / f"{name}-{width}x{height}.png")
        window.grab().save(str(shots[-1]))
    run_and_wait(window, len(BATCH))
    for index, name in ((1, "9-batch-run"), (2, "10-batch-results")):
        window.tabs.setCurrentIndex(index)
        for _ in range(5):
            QCoreApplication.processEvents()
        shots.append(HERE / f"{name}-{width}x{height}.png")
        window.grab().save(str(shots[-1]))
    window.close()
    return shots


def main() -> int:
    size = sys.argv[1] if len(sys.argv) > 1 else "1366x768"
    width, height = (int(v) for v in size.split("x"))
    work = Path(tempfile.mkdtemp(prefix="accelcal-shots-"))
    url = f"sqlite:///{work / 'records.sqlite'}"
    records(url)
    qt_app = QApplication.instance() or QApplication([])
    from app.gui.main_window import MainWindow

    window = MainWindow(out=work / "runs", paced=False, seed=4, db=url)
    window.setGeometry(0, 0, width, height)  # the whole screen of that size
    window.show()
    window.records.wait()
    window.wait_for_plans()
    setup = window.setup_tab
    setup.technician.setText("A. Tech")
    setup.dut_id.setText("SN-1043")
    setup.dut_id.editingFinished.emit()
    setup.templates.choose("5 lines, quick")
    window.wait_for_plans()
    run_and_wait(window, 1)
    folder = window.results_tab.folder
    assert folder is not None, "the run did not complete"
    print(certificate_dialog(window, folder, width, height))
    issued = issue_registered(
        folder,
        CertificateInfo(
            authorised_by="J. Smith", temperature_c=23.0, mounting="stud, 2 N m", dut_type="IEPE"
        ),
        folder / "certificate.pdf",
        url=url,
        prepared_by="A. Tech",
    )
    window.open_run(folder, switch=False)
    window.register_tab.refresh()
    window.register_tab.select(issued.number)
    names = ["1-setup", "2-run", "3-results", "4-runs", "5-sensors", "6-register"]
    window.sensors_tab.search.setText("SN-1042")
    window.setup_tab.dut_id.setText("SN-1043")  # the next sensor would be typed here
    for index, name in enumerate(names):
        window.tabs.setCurrentIndex(index)
        for _ in range(5):
            QCoreApplication.processEvents()
        path = HERE / f"{name}-{width}x{height}.png"
        window.grab().save(str(path))
        print(path)
    window.close()
    qt_app.processEvents()
    for path in batch_shots(work, url, width, height):
        print(path)
    qt_app.processEvents()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
