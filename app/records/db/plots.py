"""The drift chart of `accelcal history --plot`: sensitivity at the reference frequency over
time with its expanded-uncertainty bars, drawn with pyqtgraph on an offscreen Qt surface."""

from __future__ import annotations

import os
from pathlib import Path

from app.records.db.lab import History


def drift_chart(history: History, target: Path, *, width_px: int = 900) -> None:
    """Write a PNG chart of `history` to `target` (sensitivity in mV/(m/s^2) against date)."""
    if not history.points:
        raise ValueError(f"history: no calibrations of {history.serial} on record to plot")
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    import numpy as np
    import pyqtgraph as pg
    import pyqtgraph.exporters
    from PySide6.QtWidgets import QApplication

    qt_app = QApplication.instance() or QApplication([])
    t = np.array([p.started_utc.timestamp() for p in history.points])
    s = np.array([p.sensitivity_mv_per_ms2 for p in history.points])
    u = np.array([p.expanded_uncertainty_mv_per_ms2 or 0.0 for p in history.points])
    plot = pg.PlotWidget(axisItems={"bottom": pg.DateAxisItem()}, background="w")
    drift = history.drift_percent_per_year
    title = f"{history.serial}: sensitivity at the reference frequency"
    if drift is not None:
        title += f" (drift {drift:+.3f} % per year)"
    plot.setTitle(title, color="k", size="11pt")
    for side, label in (("left", "sensitivity in mV/(m/s²)"), ("bottom", "calibration date")):
        axis = plot.getAxis(side)
        axis.setPen("k")
        axis.setTextPen("k")
        axis.enableAutoSIPrefix(False)
        axis.setLabel(label, color="k")
    plot.getAxis("left").setWidth(80)
    plot.addItem(pg.ErrorBarItem(x=t, y=s, height=2 * u, beam=0, pen=pg.mkPen("k")))
    plot.plot(t, s, pen=pg.mkPen("b", width=2), symbol="o", symbolBrush="b")
    plot.resize(width_px, int(width_px * 0.55))
    plot.show()
    QApplication.processEvents()
    exporter = pyqtgraph.exporters.ImageExporter(plot.plotItem)
    exporter.parameters()["width"] = width_px
    written = exporter.export(str(target))
    plot.close()
    qt_app.processEvents()
    if not written:
        raise OSError(f"--plot: could not write {target}")
