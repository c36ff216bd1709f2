"""pyqtgraph plots of the window: the live Run tab and the Results tab's charts.

Everything here is called on the GUI thread only (from the Run tab's FRAME_HZ timer or a slot);
the worker thread never sees a plot item. Charts with nothing to show are replaced by a line
saying why (`ChartStack`), never drawn as empty frames with placeholder axes. The live plots
draw at most a few points per pixel of their width (min/max per pixel column, so no peak is
lost) and move their axes only when the data leaves them (a steady axis is not redrawn).
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QShowEvent
from PySide6.QtWidgets import QLabel, QStackedWidget, QWidget

from app.gui.live_view import (
    MIN_COLUMNS,
    EstimateView,
    PeriodView,
    characteristic,
    estimate_view,
    peak_decimated,
    period_view,
)
from dsp.calibration import Results
from dsp.multisine import Plan

__all__ = ["characteristic", "peak_decimated"]  # at home in live_view, used from here too

FRAME_HZ = 40  # live frames per second (>= 30 updates per second at 2 x 51.2 kS/s)
# labelled ticks of the logarithmic frequency axes (Hz): decades, then 2 and 5 between them
DECADE_TICKS_HZ = (1, 10, 100, 1000, 10000)
MINOR_TICKS_HZ = (2, 5, 20, 50, 200, 500, 2000, 5000, 20000)
REF_COLOUR, DUT_COLOUR = "#4a9ee0", "#d62728"
LEGEND_BRUSH = (0, 0, 0, 200)  # the legend readable over the traces it names
LEFT_AXIS_PX = 62  # width of each live plot's y axis: label and "-100.5" tick text
# the deviation curves of a run of several DUTs, one colour and symbol per member in the
# fixture's order (told apart where they overlap, and without colour)
# (light enough on the plots' black background)
MEMBER_COLOURS = ("#5dade2", "#f39c12", "#48c9b0", "#c39bd3", "#f1948a", "#f7dc6f", "#d5dbdb")
MEMBER_SYMBOLS = ("o", "s", "t", "d", "+", "x", "star")
DEVIATION_TITLE = "Sensitivity deviation from reference frequency"


def hz_label(frequency_hz: float) -> str:
    """'500', '1k', '2.5k'."""
    return f"{frequency_hz / 1000:g}k" if frequency_hz >= 1000 else f"{frequency_hz:g}"


def frequency_axis(plot: pg.PlotItem) -> None:
    """Logarithmic frequency axis with readable labels (pyqtgraph's own crowd together)."""
    plot.setLogMode(x=True)
    plot.getAxis("bottom").setTicks(
        [
            [(float(np.log10(f)), hz_label(f)) for f in DECADE_TICKS_HZ],
            [(float(np.log10(f)), hz_label(f)) for f in MINOR_TICKS_HZ],
        ]
    )


class ChartStack(QStackedWidget):
    """A chart, or in its place a line saying why there is none yet."""

    def __init__(self, chart: QWidget, message: str) -> None:
        super().__init__()
        self._rendered = False  # the hidden chart painted once at the stack's size (`_render`)
        self.message = QLabel(message)
        self.message.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color: #7f8c8d; font-size: 14px")
        self.chart = chart
        self.addWidget(self.message)
        self.addWidget(chart)

    def show_chart(self, shown: bool, message: str | None = None) -> None:
        """The chart (True) or the message (False; `message` replaces the text)."""
        if message is not None:
            self.message.setText(message)
        self.setCurrentWidget(self.chart if shown else self.message)

    def showEvent(self, event: QShowEvent) -> None:
        """On the first show, paint the hidden chart once when the window is idle: its first
        paint (fonts, titles, axis pictures: about 30 ms on the GUI thread) is then not paid
        when a run starts and the worker competes for the interpreter (issue 34.6)."""
        super().showEvent(event)
        if not self._rendered:
            self._rendered = True
            QTimer.singleShot(0, self._render)

    def _render(self) -> None:
        if not self.showing_chart and self.isVisible():
            self.chart.resize(self.size())  # a hidden page keeps its own size until shown
            self.chart.grab()

    @property
    def showing_chart(self) -> bool:
        return self.currentWidget() is self.chart


def follow_y(plot: pg.PlotItem, low: float, high: float) -> bool:
    """Move the y axis of `plot` only when [low, high] leaves it or fills under a quarter of
    it (with a 10 % margin): a steady axis is not regenerated every frame. Whether it moved."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return False
    span = high - low or max(abs(high), 1e-12)
    now_low, now_high = plot.getViewBox().viewRange()[1]
    if now_low <= low and high <= now_high and (now_high - now_low) <= 4 * span * 1.2:
        return False
    plot.setYRange(low - 0.1 * span, high + 0.1 * span, padding=0)
    return True


class LivePlots:
    """The Run tab's four plots: last period, spectra, deviation and phase converging (a line
    saying there is no run yet until the first period)."""

    def __init__(self) -> None:
        self.graphics = pg.GraphicsLayoutWidget()
        self.widget = ChartStack(
            self.graphics, "No run yet: the live plots appear when a run starts (tab 1, Start)."
        )
        g = self.graphics
        self.wave_plot = g.addPlot(title="Last period")
        self.wave_plot.setLabel("left", "voltage", units="V")  # auto SI prefix: mV, not x0.001
        self.wave_plot.setLabel("bottom", "time", units="s")
        self.wave_plot.addLegend(offset=(-10, 10), brush=LEGEND_BRUSH)
        self.wave_ref = self.wave_plot.plot(pen=pg.mkPen(REF_COLOUR), name="reference")
        self.wave_dut = self.wave_plot.plot(pen=pg.mkPen(DUT_COLOUR), name="DUT")
        self.wave_ref.setZValue(1)  # the reference over the DUT where they overlap
        self.spec_plot = g.addPlot(
            title="Spectra (lines marked)", labels={"left": "dB re 1 V", "bottom": "Hz"}
        )
        frequency_axis(self.spec_plot)
        self.spec_plot.addLegend(offset=(-10, 10), brush=LEGEND_BRUSH)
        self.spec_ref = self.spec_plot.plot(pen=pg.mkPen(REF_COLOUR, width=1), name="reference")
        self.spec_dut = self.spec_plot.plot(pen=pg.mkPen(DUT_COLOUR, width=1), name="DUT")
        self.spec_lines = self.spec_plot.plot(
            pen=None, symbol="t", symbolSize=6, symbolBrush="k", name="plan lines"
        )
        g.nextRow()
        self.sens_plot = g.addPlot(
            title=DEVIATION_TITLE,
            labels={"left": "%", "bottom": "Hz"},
        )
        frequency_axis(self.sens_plot)
        self.sens_plot.getAxis("left").enableAutoSIPrefix(False)  # "%", never "% (x0.001)"
        self.sens_curve = self.sens_plot.plot(pen=pg.mkPen("#2c3e50"), symbol="o", symbolSize=5)
        self.sens_err = pg.ErrorBarItem(beam=0.02, pen=pg.mkPen("#7f8c8d"))
        self.sens_plot.addItem(self.sens_err)
        self.phase_plot = g.addPlot(title="Phase", labels={"left": "degree", "bottom": "Hz"})
        frequency_axis(self.phase_plot)
        self.phase_plot.getAxis("left").enableAutoSIPrefix(False)
        self.phase_curve = self.phase_plot.plot(pen=pg.mkPen("#8e44ad"), symbol="o", symbolSize=5)
        self.phase_err = pg.ErrorBarItem(beam=0.02, pen=pg.mkPen("#7f8c8d"))
        self.phase_plot.addItem(self.phase_err)
        for plot in self.plots:
            plot.disableAutoRange()  # the axes follow the data in steps (follow_y)
            # a fixed width: new tick labels never re-lay the four plots out mid-run
            plot.getAxis("left").setWidth(LEFT_AXIS_PX)
            # no grid: a grid is drawn by the axes over the whole plot, so every new curve
            # would repaint (and re-render the text of) all eight axes
        self._ranges: dict[int, tuple[float, float]] = {}  # x range set per plot
        # a run of several DUTs: each member's deviation curve by its position (`members`)
        self.member_curves: dict[str, pg.PlotDataItem] = {}
        self._labels: dict[str, str] = {}  # what `members` last made them for
        self._member_legend: pg.LegendItem | None = None

    @property
    def plots(self) -> tuple[pg.PlotItem, ...]:
        return (self.wave_plot, self.spec_plot, self.sens_plot, self.phase_plot)

    @property
    def curves(self) -> tuple[pg.PlotDataItem, ...]:
        return (
            self.wave_ref,
            self.wave_dut,
            self.spec_ref,
            self.spec_dut,
            self.spec_lines,
            self.sens_curve,
            self.phase_curve,
        )

    def clear(self) -> None:
        """Empty every curve and error bar (a new run starts from nothing)."""
        for curve in self.curves:
            curve.setData([], [])
        for bars in (self.sens_err, self.phase_err):
            bars.setData(x=np.array([]), y=np.array([]), height=np.array([]))
        for plot in self.plots:
            plot.setYRange(0, 1, padding=0)  # the first data sets its own range
        self._ranges.clear()
        for curve in self.member_curves.values():  # kept for the next run of the same DUTs
            curve.setData([], [])
        self.widget.show_chart(False)

    def members(self, labels: dict[str, str]) -> None:
        """One deviation curve per member of a run of several DUTs, `labels` {position: what
        the legend says} in the fixture's order ({}: a single run, none). Made before the
        run's first period (`RunTab.opened`), so the legend never re-lays the plots mid-run;
        the first member's phase stays the single run's phase curve (its title names it); its
        U is on the Results tab (error bars of one DUT over every DUT's curve would read as
        theirs). The legend at the top left: the characteristic rises to the right. The same
        labels again: the curves kept (made once: about 4 ms of the GUI thread each)."""
        if labels == self._labels and (self.member_curves or not labels):
            return
        self._labels = dict(labels)
        for curve in self.member_curves.values():
            self.sens_plot.removeItem(curve)  # and from its legend
        self.member_curves = {}
        self.sens_curve.setVisible(not labels)
        self.sens_err.setVisible(not labels)
        self.sens_plot.setTitle(f"{DEVIATION_TITLE}, per DUT" if labels else DEVIATION_TITLE)
        lead = next(iter(labels.values()), "")
        self.phase_plot.setTitle(f"Phase ({lead})" if labels else "Phase")
        self._name_dut(f"DUT {lead}" if labels else "DUT")  # the traces of the run's own DUT
        if self._member_legend is not None:
            self._member_legend.clear()
            self._member_legend.setVisible(bool(labels))
        if not labels:
            return
        if self._member_legend is None:
            self._member_legend = self.sens_plot.addLegend(offset=(10, 10), brush=LEGEND_BRUSH)
        self._member_legend.setVisible(True)
        for i, (position, label) in enumerate(labels.items()):
            colour = MEMBER_COLOURS[i % len(MEMBER_COLOURS)]
            self.member_curves[position] = self.sens_plot.plot(
                pen=pg.mkPen(colour, width=2),
                symbol=MEMBER_SYMBOLS[i % len(MEMBER_SYMBOLS)],
                symbolSize=7,
                symbolBrush=colour,
                symbolPen=pg.mkPen(colour),
                name=label,
            )

    def _name_dut(self, text: str) -> None:
        """The legend's name of the DUT's trace and spectrum."""
        for plot, curve in ((self.wave_plot, self.wave_dut), (self.spec_plot, self.spec_dut)):
            for sample, label in plot.legend.items:
                if sample.item is curve and label.text != text:
                    label.setText(text)

    def show_member(self, position: str, view: EstimateView) -> None:
        """The deviation of the member at `position` (its curve, `members`), the y axis
        following every member's curve."""
        curve = self.member_curves.get(position)
        if curve is None:
            return
        c = view.characteristic
        curve.setData(c.frequency_hz, c.deviation_percent)
        lows, highs = [], []  # every member's deviation (their U is on the Results tab)
        for other in self.member_curves.values():
            y = other.getData()[1]
            if y is not None and len(y):
                lows.append(float(np.nanmin(y)))
                highs.append(float(np.nanmax(y)))
        self._lines_x(c.frequency_hz)
        if c.frequency_hz.size and lows:
            follow_y(self.sens_plot, min(lows), max(highs))

    def prepare(self, plan: Plan) -> None:
        """Show the charts with the x ranges of `plan` before its first period, so the
        layout and the axes are settled before the live frames begin."""
        self.widget.show_chart(True)
        self._period_x(plan.period_samples, plan.sample_rate_hz)
        self._lines_x(np.asarray(plan.frequencies_hz, dtype=float))

    def _period_x(self, samples: int, sample_rate_hz: float) -> None:
        """The x ranges of a period of `samples` and of its spectrum (one home for both:
        `prepare` and `draw_period` set the same ranges, so the first frame moves no axis)."""
        self._x_range(self.wave_plot, 0.0, (samples - 1) / sample_rate_hz if samples else 1.0)
        if samples >= 2:  # a spectrum has bins 1 .. samples // 2
            low, high = sample_rate_hz / samples, sample_rate_hz / samples * (samples // 2)
            self._x_range(self.spec_plot, float(np.log10(low)), float(np.log10(high)))

    def _lines_x(self, frequencies_hz: np.ndarray) -> None:
        """The x range (log10 Hz) of the deviation and phase plots over `frequencies_hz`."""
        if frequencies_hz.size:
            logf = np.log10(frequencies_hz)
            for plot in (self.sens_plot, self.phase_plot):
                self._x_range(plot, float(logf.min()) - 0.05, float(logf.max()) + 0.05)

    def _x_range(self, plot: pg.PlotItem, low: float, high: float) -> None:
        """Set the x range once per run (and again only when it changes)."""
        if self._ranges.get(id(plot)) != (low, high):
            self._ranges[id(plot)] = (low, high)
            plot.setXRange(low, high, padding=0.02)

    def columns(self) -> int:
        """Pixel columns of the period plot (MIN_COLUMNS before it is laid out)."""
        return max(MIN_COLUMNS, int(self.wave_plot.getViewBox().width()))

    def draw_period(self, reference: np.ndarray, dut: np.ndarray, plan: Plan) -> None:
        """The last period of both channels and their spectra, the plan's lines marked (the
        view made here; a live run's comes made by the worker: `show_period`)."""
        self.show_period(period_view(reference, dut, plan, self.columns()))

    def show_period(self, view: PeriodView) -> None:
        """Set the points of a period's `view` (computed off this thread): nothing but
        setData and, when the data leaves them, the axes."""
        self.widget.show_chart(True)
        self.wave_ref.setData(*view.reference, skipFiniteCheck=True)
        self.wave_dut.setData(*view.dut, skipFiniteCheck=True)
        self._period_x(view.samples, view.sample_rate_hz)
        if view.samples:
            follow_y(self.wave_plot, *view.wave_range_v)
        self.spec_ref.setData(view.spectrum_hz, view.spectra_db[0], skipFiniteCheck=True)
        self.spec_dut.setData(view.spectrum_hz, view.spectra_db[1], skipFiniteCheck=True)
        if view.lines is not None:
            self.spec_lines.setData(*view.lines, skipFiniteCheck=True)
        if view.spectrum_hz.size:
            follow_y(self.spec_plot, *view.spectrum_range_db)

    def draw_characteristic(self, results: Results) -> None:
        """Deviation and phase per line with their expanded uncertainties as error bars (the
        view made here; a live run's comes made by the worker: `show_characteristic`)."""
        self.show_characteristic(estimate_view(results))

    def show_characteristic(self, view: EstimateView) -> None:
        """Set the points of an estimate's `view` (computed off this thread)."""
        c, logf = view.characteristic, view.log_frequency
        f, dev, phase = c.frequency_hz, c.deviation_percent, c.phase_deg
        self.sens_curve.setData(f, dev)
        if not self.member_curves:  # (setData would show the bars `members` hid)
            self.sens_err.setData(x=logf, y=dev, height=2 * c.deviation_expanded_percent)
        self.phase_curve.setData(f, phase)
        self.phase_err.setData(x=logf, y=phase, height=2 * c.phase_expanded_deg)
        self._lines_x(f)
        if f.size:
            if not self.member_curves:  # several DUTs: the y axis follows their curves
                follow_y(self.sens_plot, *view.deviation_range)
            follow_y(self.phase_plot, *view.phase_range)


def draw_bands(mag: pg.PlotItem, phase: pg.PlotItem, results: Results | None) -> None:
    """Deviation and phase with their expanded-uncertainty bands (None: empty charts)."""
    for plot in (mag, phase):
        plot.clear()
    if results is None:
        return
    c = characteristic(results)
    f = c.frequency_hz
    for plot, v, u in (
        (mag, c.deviation_percent, c.deviation_expanded_percent),
        (phase, c.phase_deg, c.phase_expanded_deg),
    ):
        lower = plot.plot(f, v - u, pen=pg.mkPen("#9bb7e0"))
        upper = plot.plot(f, v + u, pen=pg.mkPen("#9bb7e0"))
        plot.addItem(pg.FillBetweenItem(lower, upper, brush=pg.mkBrush(155, 183, 224, 110)))
        plot.plot(f, v, pen=pg.mkPen("#1f3a68", width=2), symbol="o", symbolSize=5)
