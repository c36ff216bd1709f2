"""Write the example files of examples/ (README.md's `accelcal analyze` examples run on them).

    PYTHONPATH=. python examples/make_examples.py [--out examples]

All come from the simulated stand (piezo DUT, 10.2 mV/(m/s^2) nominal, seed 1) on a small plan
that keeps each file well under 1 MB: the ISO 266 lines 10-400 Hz at fs 1 kHz, a period of 500
samples (0.5 s, bins 2 Hz), 5 m/s^2 per line, reference line 160 Hz:

- recording.h5    `accelcal simulate`'s format: fade-in, 2 settling and 8 analysed periods
- recording.csv   its 8 analysed periods, reference and DUT in V, with the skew header line
- recording.tdms  the same in a TDMS file (group Accel, channels ref and dut; wf_increment,
                  unit_string V, accelcal_skew_s on the DUT channel)
- runs/<run-id>/  a complete run folder of `accelcal run --sim` on that plan (4 periods); a
                  run folder is never overwritten: remove the old one (and change its name in
                  README.md) when regenerating
- ref-table.csv   the simulated reference standard's calibration table (for `accelcal refs add`)

The simulated stand's reference channel carries 1.0 mV/(m/s^2) nominal through a conditioning
gain of 10, and its DUT channel is sampled 4 us after the reference: hence the CSV/TDMS
examples' `--reference-sensitivity 1.0 --reference-gain 10` and skew 4e-06 s.
"""

from __future__ import annotations

import argparse
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

PLAN_ARGS = (10.0, 400.0, 1000.0, 500)  # ISO 266 from, to (Hz), fs (Hz), period (samples)
SEED = 1
LEVEL_MS2 = 5.0
REFERENCE_U_REL = 0.005  # relative expanded uncertainty (k = 2) of the reference's table

log = logging.getLogger("make_examples")


def small_plan():
    """The examples' plan (see the module docstring)."""
    from dsp import iso266
    from dsp.multisine import make_plan

    low, high, fs, period = PLAN_ARGS
    return make_plan(iso266.nominal_frequencies(low, high), fs, period, LEVEL_MS2, 160.0)


def write_recordings(out: Path) -> None:
    """recording.h5 (simulated), and its analysed periods as recording.csv and recording.tdms."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    from app.io.hdf5 import read_recording
    from app.procedure.simulate import simulate

    h5 = out / "recording.h5"
    simulate(
        h5, dut="piezo", level_ms2=LEVEL_MS2, periods=8, seed=SEED, plan=small_plan(), overwrite=True
    )
    rec = read_recording(h5)
    start = rec.settle_periods * rec.period_samples
    reference, dut = rec.reference_v[start:], rec.dut_v[start:]
    skew_s = rec.chain.skew_s
    rows = "\n".join(f"{r:.7f},{d:.7f}" for r, d in zip(reference, dut, strict=True))
    (out / "recording.csv").write_text(
        f"# simulated piezo DUT, seed {SEED}: {rec.plan.sample_rate_hz:g} Hz, period "
        f"{rec.period_samples} samples, 8 periods, volts\n"
        f"# skew_s = {skew_s:g}\nreference_v,dut_v\n{rows}\n",
        encoding="ascii",
    )
    increment = 1.0 / rec.plan.sample_rate_hz
    volts = {"unit_string": "V", "wf_increment": increment, "wf_start_offset": 0.0}
    with TdmsWriter(out / "recording.tdms") as writer:
        writer.write_segment(
            [
                RootObject({"description": f"simulated piezo DUT, seed {SEED}"}),
                GroupObject("Accel"),
                ChannelObject("Accel", "ref", np.asarray(reference), properties=volts),
                ChannelObject(
                    "Accel",
                    "dut",
                    np.asarray(dut),
                    properties={**volts, "accelcal_skew_s": float(skew_s or 0.0)},
                ),
            ]
        )


def write_run(out: Path) -> None:
    """A complete simulated run on the small plan, under out/runs/."""
    import dsp.multisine as multisine
    from app.procedure.run import RunRequest, execute

    low, high, fs, period = PLAN_ARGS
    multisine.PRESETS["example"] = multisine.Preset(
        "example", "the examples' small plan", low, high, fs, period
    )
    finished = execute(
        RunRequest(
            dut="piezo",
            dut_id="SN-EX1",
            preset="example",
            periods=4,
            seed=SEED,
            tolerance_percent=5.0,
            out=out / "runs",
            stored_response=False,
        )
    )
    log.info("run %s: %s", finished.record.run_id, finished.status)


def write_reference_table(out: Path) -> None:
    """The simulated reference standard's certificate table, ISO 266 lines 10 Hz-10 kHz."""
    from sim.stand import SimulatedStand

    chain = SimulatedStand("piezo", seed=SEED).reference_chain()
    lines = ["frequency_hz,sensitivity_mv_per_ms2,relative_expanded_uncertainty_percent,phase_deg"]
    for f, s, ph in zip(
        chain.frequencies_hz, chain.sensitivity_mv_per_ms2, chain.phase_deg, strict=True
    ):
        if 10.0 <= f <= 10_000.0:
            lines.append(f"{f:g},{s:.5f},{100 * REFERENCE_U_REL:g},{ph:.3f}")  # percent
    (out / "ref-table.csv").write_text("\n".join(lines) + "\n", encoding="ascii")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    os.environ.setdefault("XDG_DATA_HOME", tempfile.mkdtemp(prefix="accelcal-examples-"))
    args.out.mkdir(parents=True, exist_ok=True)
    write_recordings(args.out)
    write_run(args.out)
    write_reference_table(args.out)


if __name__ == "__main__":
    main()
