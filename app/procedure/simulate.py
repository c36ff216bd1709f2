"""`accelcal simulate`: a recording from the simulated stand through the `Daq` interface.

Open loop (closed-loop equalisation belongs to the calibration procedure): the drive of every
line is pre-equalised with the stand's nominal sampled model, faded in over one period, then
`settle` periods pass before the analysed periods. The recording carries the drive loopback,
the reference chain the analysis may know (certificate, nominal gains, skew), the stand's
budget and the simulated truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.errors import Refusal
from app.files import FileExistsRefusal, check_target, staged
from app.io.hdf5 import RecordingWriter, Truth
from app.io.vocabulary import RunStatus
from app.procedure.phase_store import stored_phases
from app.records.run_folder import refuse_in_run_folder
from app.stand.config import load as load_stand
from dsp.crestfactor import synthesize
from dsp.multisine import Plan, fade_envelope, preset_plan
from hardware.errors import HardwareError
from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.models import DUT_CATALOGUE, plan_preset_for
from sim.stand import Fault, SimulatedStand

AO_RANGE_V = 10.0
AI_RANGES_V = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)  # an M-series board's input ranges


class SimulationError(Refusal):
    """The simulation cannot be run as asked (level beyond the drive range, ...)."""


@dataclass(frozen=True)
class SimulatedRun:
    """What `simulate` produced."""

    path: Path
    plan: Plan
    periods: int
    settle_periods: int
    truth: Truth
    drive_peak_v: float
    ranges_v: dict[str, float]


def pick_range(peak_v: float, channel: str) -> float:
    """Smallest input range with 50 % headroom over a predicted peak, in V."""
    for range_v in AI_RANGES_V:
        if 1.5 * peak_v <= range_v:
            return range_v
    raise SimulationError(
        f"--level: the predicted {channel} signal peak {peak_v:.3g} V exceeds the largest "
        f"input range {AI_RANGES_V[-1]:g} V; lower the level"
    )


def equalised_drive(stand: SimulatedStand, plan: Plan) -> np.ndarray:
    """One period of drive (V) giving the plan's table acceleration on the nominal model."""
    response = stand.table_response(plan.frequencies_hz)
    return synthesize(
        plan.bins,
        plan.amplitudes_ms2 / np.abs(response),
        plan.phases_rad - np.angle(response),
        plan.period_samples,
    )


def simulate(
    out: str | Path,
    *,
    dut: str = "piezo",
    level_ms2: float = 5.0,
    periods: int = 8,
    seed: int = 0,
    plan: Plan | None = None,
    settle: int = 2,
    faults: tuple[Fault, ...] = (),
    paced: bool = False,
    systematic: bool = True,
    overwrite: bool = False,
) -> SimulatedRun:
    """Simulate a calibration recording of a catalogue DUT and write it to `out` (HDF5), under
    a temporary name until it is whole; an existing `out` is refused unless `overwrite`.

    `systematic=False` leaves the stand exactly at its nominal values (no drawn deviations).
    A stand error (an injected fault) is raised after the recording so far is in place, marked
    aborted."""
    if dut not in DUT_CATALOGUE:
        raise SimulationError(
            f"--dut: unknown {dut!r}; the catalogue has {', '.join(DUT_CATALOGUE)}"
        )
    if periods < 1:
        raise SimulationError(f"--periods: must be >= 1, got {periods}")
    path = _target(out, overwrite)
    if plan is None:
        plan = preset_plan(plan_preset_for(dut), level_ms2=level_ms2, optimiser=stored_phases)
    stand = SimulatedStand(dut, seed=seed, faults=faults, paced=paced, systematic=systematic)
    sensor = stand.dut
    peaks = plan.predicted_peaks()
    reference_peak = peaks.acceleration_ms2 * stand.model.reference.sensitivity_mv_per_ms2 * 1e-3
    reference_peak *= stand.model.reference_gain
    dut_peak = (
        peaks.acceleration_ms2
        * float(np.max(np.abs(sensor.sensitivity(plan.frequencies_hz))))
        * 1e-3
    )
    stroke = stand.model.exciter.stroke_peak_to_peak_m
    if peaks.displacement_peak_to_peak_m > stroke:
        raise SimulationError(
            f"--level: {level_ms2:g} m/s^2 needs {1e3 * peaks.displacement_peak_to_peak_m:.1f} mm "
            f"p-p of table travel, beyond the exciter's {1e3 * stroke:g} mm stroke"
        )
    ranges = {
        "reference": pick_range(reference_peak, "reference"),
        "dut": pick_range(max(dut_peak, 1e-3), "DUT"),
    }
    config = DaqConfig(
        plan.sample_rate_hz,
        plan.period_samples,
        OutputChannel("sim/ao0", AO_RANGE_V),
        (
            InputChannel("reference", "sim/ai0", ranges["reference"]),
            InputChannel("dut", "sim/ai1", ranges["dut"]),
            InputChannel("drive", "sim/ai2", AO_RANGE_V),
        ),
    )
    stand.configure(config)
    drive = equalised_drive(stand, plan)
    drive_peak = float(np.max(np.abs(drive)))
    if drive_peak > AO_RANGE_V:
        raise SimulationError(
            f"--level: needs a {drive_peak:.3g} V drive peak, beyond the +-{AO_RANGE_V:g} V output"
        )
    truth_values = stand.truth(
        plan.frequencies_hz, rms_ms2=float(np.sqrt(np.sum(plan.amplitudes_ms2**2) / 2))
    )
    truth = Truth(
        plan.frequencies_hz,
        np.abs(truth_values),
        np.degrees(np.angle(truth_values)),
        {"dut": dut, "description": sensor.description, "level_ms2": level_ms2, "seed": seed},
    )
    chain = stand.reference_chain()
    settle_periods = 1 + settle  # the fade-in period, then the settling ones
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with staged(path, overwrite=overwrite) as temporary:  # no reader sees it half-written
            with RecordingWriter(
                temporary,
                plan,
                chain,
                stand.sim_budget.budget,
                settle_periods=settle_periods,
                with_drive=True,
                ranges_v={**ranges, "drive": AO_RANGE_V},
                cmc=load_stand(None).cmc,  # the built-in stand's, whose budget it records
            ) as writer:
                writer.write_truth(truth)
                error = _record(stand, writer, drive, plan, settle_periods + periods)
    except FileExistsRefusal as exc:  # created by someone else meanwhile
        raise SimulationError(f"--out: {exc} (--overwrite replaces it)") from None
    if error is not None:
        raise error  # after the partial recording, marked aborted, is in place
    return SimulatedRun(path, plan, periods, settle_periods, truth, drive_peak, ranges)


def _target(out: str | Path, overwrite: bool) -> Path:
    """The recording to write; SimulationError naming --out when it exists (unless
    `overwrite`) or lies in a run folder (never, a run's record is not changed)."""
    path = Path(out)
    try:
        check_target(path, overwrite=overwrite)
        refuse_in_run_folder(path)
    except FileExistsRefusal as exc:
        raise SimulationError(f"--out: {exc} (--overwrite replaces it)") from None
    except ValueError as exc:
        raise SimulationError(f"--out: {exc}") from None
    return path


def _record(
    stand: SimulatedStand, writer: RecordingWriter, drive: np.ndarray, plan: Plan, count: int
) -> HardwareError | None:
    """Fade in, then record `count` periods; mark the recording complete, or aborted with the
    stand's error (returned, to be raised once the partial recording is in place)."""
    fade = fade_envelope(plan.period_samples, 1, "in")
    try:
        stand.start(drive * fade)
        for index in range(count):
            block = stand.read_period()
            writer.append(block[0], block[1], block[2])
            if index == 0:
                stand.write_period(drive)
    except HardwareError as exc:
        writer.set_status(RunStatus.ABORTED, f"{type(exc).__name__}: {exc}")
        return exc
    finally:
        stand.stop()
    writer.set_status(RunStatus.COMPLETE)
    return None
