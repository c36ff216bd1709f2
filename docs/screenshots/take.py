"""Screenshots of every tab at 1366x768 (offscreen): a records database with two customers'
sensors and a history, one simulated run of a registered sensor, each tab grabbed.

    QT_QPA_PLATFORM=offscreen python docs/screenshots/take.py [WIDTHxHEIGHT]
"""

from __future__ import annotations

import os
import sys
import tempfile
from datetime import UTC, date, datetime
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import QCoreApplication, QEventLoop, QTimer
from PySide6.QtWidgets import QApplication

from app.db.engine import open_engine
from app.db.lab import Lab
from app.db.models import Run, Stand

HERE = Path(__file__).resolve().parent


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
    history = [
        ("SN-1042", date(2022, 11, 2), 10.22, 0.06),
        ("SN-1042", date(2023, 11, 6), 10.25, 0.06),
        ("SN-1042", date(2024, 11, 4), 10.27, 0.05),
        ("SN-1042", date(2025, 11, 3), 10.31, 0.05),
        ("BK-2210", date(2024, 6, 12), 9.98, 0.04),
    ]
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


def main() -> int:
    size = sys.argv[1] if len(sys.argv) > 1 else "1366x768"
    width, height = (int(v) for v in size.split("x"))
    work = Path(tempfile.mkdtemp(prefix="accelcal-shots-"))
    url = f"sqlite:///{work / 'records.sqlite'}"
    records(url)
    qt_app = QApplication.instance() or QApplication([])
    from app.gui.main_window import MainWindow

    window = MainWindow(out=work / "runs", paced=False, seed=4, db=url)
    window.resize(width, height)
    window.show()
    window.records.wait()
    window.wait_for_plans()
    window.dut_id.setText("SN-1043")
    window.dut_id.editingFinished.emit()
    window.nominal.setValue(0.0)  # the simulated piezo is not a 352C33
    window.periods.setValue(4)
    loop = QEventLoop()
    window.run_finished.connect(lambda _f: QTimer.singleShot(300, loop.quit))
    window.start_run()
    loop.exec()
    names = ["1-setup", "2-run", "3-results", "4-runs", "5-sensors"]
    window.sensors_tab.search.setText("SN-1042")
    window.dut_id.setText("SN-1043")
    for index, name in enumerate(names):
        window.tabs.setCurrentIndex(index)
        for _ in range(5):
            QCoreApplication.processEvents()
        path = HERE / f"{name}-{width}x{height}.png"
        window.grab().save(str(path))
        print(path)
    window.close()
    qt_app.processEvents()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
