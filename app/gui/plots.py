"""pyqtgraph plots of the window: the live Run tab and the Results tab's charts.

Everything here is called on the GUI thread only (from the window's 25 Hz timer or a slot);
the worker thread never sees a plot item.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pyqtgraph as pg

from dsp.calibration import Results
from dsp.characteristic import Characteristic
from dsp.characteristic import characteristic as dsp_characteristic
from dsp.multisine import Plan
from dsp.spectral import period_spectrum

FRAME_HZ = 25
# labelled ticks of the logarithmic frequency axes (Hz): decades, then 2 and 5 between them
DECADE_TICKS_HZ = (1, 10, 100, 1000, 10000)
MINOR_TICKS_HZ = (2, 5, 20, 50, 200, 500, 2000, 5000, 20000)
MAX_POINTS = 4000  # enough points of a period for the eye


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


def characteristic(results: Results) -> Characteristic:
    """dsp.characteristic's deviation, phase and their U (the numbers the certificate draws),
    with a U that is not stated drawn as 0."""
    c = dsp_characteristic(results)
    return dataclasses.replace(
        c,
        deviation_expanded_percent=np.nan_to_num(c.deviation_expanded_percent),
        phase_expanded_deg=np.nan_to_num(c.phase_expanded_deg),
    )


class LivePlots:
    """The Run tab's four plots: last period, spectra, deviation and phase converging."""

    def __init__(self) -> None:
        self.widget = pg.GraphicsLayoutWidget()
        g = self.widget
        self.wave_plot = g.addPlot(title="Last period")
        self.wave_plot.setLabel("left", "voltage", units="V")  # auto SI prefix: mV, not x0.001
        self.wave_plot.setLabel("bottom", "time", units="s")
        self.wave_ref = self.wave_plot.plot(pen=pg.mkPen("#1f77b4"), name="reference")
        self.wave_dut = self.wave_plot.plot(pen=pg.mkPen("#d62728"), name="DUT")
        self.spec_plot = g.addPlot(
            title="Spectra (lines marked)", labels={"left": "dB re 1 V", "bottom": "Hz"}
        )
        frequency_axis(self.spec_plot)
        self.spec_ref = self.spec_plot.plot(pen=pg.mkPen("#1f77b4", width=1))
        self.spec_dut = self.spec_plot.plot(pen=pg.mkPen("#d62728", width=1))
        self.spec_lines = self.spec_plot.plot(pen=None, symbol="t", symbolSize=6, symbolBrush="k")
        g.nextRow()
        self.sens_plot = g.addPlot(
            title="Sensitivity deviation from reference frequency",
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

    def draw_period(self, reference: np.ndarray, dut: np.ndarray, plan: Plan) -> None:
        """The last period of both channels and their spectra, the plan's lines marked."""
        t = np.arange(reference.size) / plan.sample_rate_hz
        step = max(1, reference.size // MAX_POINTS)
        self.wave_ref.setData(t[::step], reference[::step])
        self.wave_dut.setData(t[::step], dut[::step])
        spectra = np.abs(period_spectrum(np.vstack([reference, dut]))) + 1e-12
        f = np.arange(spectra.shape[1]) * plan.sample_rate_hz / reference.size
        self.spec_ref.setData(f[1:], 20 * np.log10(spectra[0, 1:]))
        self.spec_dut.setData(f[1:], 20 * np.log10(spectra[1, 1:]))
        if reference.size == plan.period_samples:
            self.spec_lines.setData(plan.frequencies_hz, 20 * np.log10(spectra[0, plan.bins]))

    def draw_characteristic(self, results: Results) -> None:
        """Deviation and phase per line with their expanded uncertainties as error bars."""
        c = characteristic(results)
        f, dev, phase = c.frequency_hz, c.deviation_percent, c.phase_deg
        logf = np.log10(f)
        self.sens_curve.setData(f, dev)
        self.sens_err.setData(x=logf, y=dev, height=2 * c.deviation_expanded_percent)
        self.phase_curve.setData(f, phase)
        self.phase_err.setData(x=logf, y=phase, height=2 * c.phase_expanded_deg)


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
