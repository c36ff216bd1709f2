"""Analytic two-channel recordings with a known DUT response, for tests and `make demo`.

Usage: python -m tests.synthetic OUT.h5 [--periods L] [--noise V] [--seed S]
writes a piezo-plan recording of a capacitive-like DUT (35 mV/(m/s^2) behind a second-order
low-pass at 200 Hz) measured against a flat 1 mV/(m/s^2) reference, with white noise on both
channels. The truth is exactly known, so the analysis must recover it within its uncertainty.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

from app.io.hdf5 import Recording, write_recording
from app.procedure.phase_store import stored_phases
from dsp.calibration import ReferenceChain
from dsp.crestfactor import synthesize
from dsp.multisine import Plan, preset_plan
from dsp.uncertainty import Budget

Response = Callable[[np.ndarray], np.ndarray]


def lowpass_response(
    sensitivity_mv_per_ms2: float = 35.0, corner_hz: float = 200.0, q: float = 0.707
) -> Response:
    """Complex sensitivity S(f) in mV/(m/s^2) of a second-order low-pass DUT."""

    def response(frequency_hz: np.ndarray) -> np.ndarray:
        s = 1j * np.asarray(frequency_hz, dtype=float) / corner_hz
        return sensitivity_mv_per_ms2 / (1.0 + s / q + s**2)

    return response


def channel_periods(
    plan: Plan, sensitivity_mv_per_ms2: np.ndarray, gain: float = 1.0, delay_s: float = 0.0
) -> np.ndarray:
    """One noiseless period in volts of a sensor with complex sensitivity per line (mV/(m/s^2)),
    behind a gain (V/V), sampled `delay_s` late."""
    amplitude = plan.amplitudes_ms2 * np.abs(sensitivity_mv_per_ms2) * 1e-3 * gain
    phase = (
        plan.phases_rad
        + np.angle(sensitivity_mv_per_ms2)
        + 2 * np.pi * plan.frequencies_hz * delay_s
    )
    return synthesize(plan.bins, amplitude, phase, plan.period_samples)


def make_recording(
    plan: Plan,
    dut: Response,
    *,
    periods: int = 8,
    reference_sensitivity_mv_per_ms2: float = 1.0,
    reference_noise_v: float = 0.0,
    dut_noise_v: float = 0.0,
    skew_s: float = 0.0,
    dut_gain: float = 1.0,
    seed: int = 0,
    budget: Budget | None = None,
    settle_periods: int = 0,
) -> Recording:
    """A recording of `periods` periods with white noise (V rms per sample) on each channel."""
    rng = np.random.default_rng(seed)
    reference_line = np.full(len(plan.lines), reference_sensitivity_mv_per_ms2, dtype=complex)
    ref_period = channel_periods(plan, reference_line)
    dut_period = channel_periods(plan, dut(plan.frequencies_hz), dut_gain, skew_s)
    n = plan.period_samples * periods
    reference = np.tile(ref_period, periods) + reference_noise_v * rng.standard_normal(n)
    dut_v = np.tile(dut_period, periods) + dut_noise_v * rng.standard_normal(n)
    chain = ReferenceChain.flat(reference_sensitivity_mv_per_ms2, dut_gain=dut_gain, skew_s=skew_s)
    return Recording(
        sample_rate_hz=plan.sample_rate_hz,
        period_samples=plan.period_samples,
        reference_v=reference,
        dut_v=dut_v,
        plan=plan,
        chain=chain,
        budget=budget if budget is not None else Budget(()),
        settle_periods=settle_periods,
        ranges_v={"reference": 10.0, "dut": 10.0},
        source="synthetic",
    )


def write_csv(path, recording: Recording, *, header: bool = True, skew_s: float | None = None):
    """Write a recording's channels as CSV (reference, DUT in V, shortest round-trip repr), with
    an optional `# skew_s = ...` comment line and a header line."""
    lines = [] if skew_s is None else [f"# skew_s = {skew_s!r}"]
    if header:
        lines.append("reference_v,dut_v")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + ("\n" if lines else ""))
        for a, b in zip(recording.reference_v.tolist(), recording.dut_v.tolist(), strict=True):
            f.write(f"{a!r},{b!r}\n")


def write_tdms(
    path,
    recording: Recording,
    *,
    group: str = "accel",
    names: tuple[str, str] = ("reference", "dut"),
    skew_s: float | None = None,
    properties: dict | None = None,
) -> None:
    """Write a recording's channels to TDMS with npTDMS's writer, one segment per period (as a
    logger appends), wf_increment = 1/fs on each channel; `skew_s` as the file property
    accelcal_skew_s; `properties` added to every channel."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    n = recording.period_samples
    root = RootObject({} if skew_s is None else {"accelcal_skew_s": skew_s})
    props = {
        "wf_increment": 1.0 / recording.sample_rate_hz,
        "unit_string": "V",
        **(properties or {}),
    }
    with TdmsWriter(str(path)) as writer:
        for start in range(0, recording.reference_v.size, n):
            channels = [
                ChannelObject(group, name, x[start : start + n], properties=props)
                for name, x in zip(names, (recording.reference_v, recording.dut_v), strict=True)
            ]
            writer.write_segment([root, GroupObject(group), *channels])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="HDF5 file to write")
    parser.add_argument("--periods", type=int, default=8)
    parser.add_argument("--noise", type=float, default=2e-3, help="V rms per sample")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    from pathlib import Path

    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    plan = preset_plan("piezo", level_ms2=5.0, optimiser=stored_phases)
    recording = make_recording(
        plan,
        lowpass_response(),
        periods=args.periods,
        reference_noise_v=args.noise / 10,
        dut_noise_v=args.noise,
        seed=args.seed,
    )
    write_recording(args.out, recording)
    print(f"wrote {args.out}: {args.periods} periods of the piezo plan, DUT 35 mV/(m/s^2) low-pass")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
