"""The lpm analysis of a long record read a batch of periods at a time against the whole record
in memory (issue 34 point 4): agreement and wall-time ratio.

For each period count, the first P analysed periods of one simulated recording (`accelcal
simulate --dut piezo`, 25 lines, 2 s periods of 12 000 samples, with its drive) are analysed by
dsp.lpm_record.record_estimate (the record in memory) and by record_estimate_batches (batches
of 16 periods, the spectra held within 12 bins of the period grid, what `analyze` does over 16
periods). Printed: the largest relative difference of H, type A (magnitude and phase), the line
noise and the DUT's harmonic distortion; the nonlinear fit's detection bins, p-values and
"found" of both; and, as the whole record's own rounding, how much its type A and noise move
when its DFT is taken with a complex FFT instead of rfft. Wall times are a ratio within the run
(with the load average); the agreement does not depend on the load.

Run: python bench/lpm_batches.py [P ...]   (default 10 20 40 300; --smoke: 20)
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.io.hdf5 import read_recording  # noqa: E402
from dsp import lpm  # noqa: E402
from dsp.lpm_record import hum_bins, record_estimate, record_estimate_batches  # noqa: E402

log = logging.getLogger("lpm_batches")


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    a, b = np.asarray(a, dtype=complex), np.asarray(b, dtype=complex)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300)))


def _rounding(reference: np.ndarray, dut: np.ndarray, plan, periods: int) -> tuple[float, float]:
    """How far the whole record's LPM type A and noise move with a complex FFT for rfft."""
    n = periods * plan.period_samples
    lines, excluded, size = plan.bins * periods, hum_bins(plan, periods), n // 2 + 1
    a = lpm.estimate(reference.reshape(1, -1), dut.reshape(1, -1), lines, excluded_bins=excluded)
    y = np.fft.fft(dut.reshape(-1))[:size] * (2.0 / n)
    u = np.fft.fft(reference.reshape(-1))[:size] * (2.0 / n)
    b = lpm.estimate_spectra(y, u, lines, size, excluded_bins=excluded)
    return _relative(b.relative_type_a, a.relative_type_a), _relative(b.dut_noise_v, a.dut_noise_v)


def compare(path: Path, periods: int) -> None:
    r = read_recording(path)
    reference, dut = r.period_range(0, periods)
    n = r.period_samples
    start = r.settle_periods * n
    assert r.drive_v is not None
    drive = np.asarray(r.drive_v)[start : start + reference.size].reshape(reference.shape)
    t0 = time.perf_counter()
    whole = record_estimate(reference, dut, r.plan, drive_blocks=drive)
    t1 = time.perf_counter()
    batches = (
        (reference[a : a + 16], dut[a : a + 16], drive[a : a + 16]) for a in range(0, periods, 16)
    )
    streamed = record_estimate_batches(batches, periods, r.plan)
    t2 = time.perf_counter()
    e, f = whole.estimate, streamed.estimate
    w, s = whole.nonlinear, streamed.nonlinear
    assert w is not None and s is not None
    round_a, round_noise = _rounding(reference, dut, r.plan, periods)
    log.info(
        "P = %d: H %.1e, type A %.1e / phase %.1e, noise %.1e, harmonic distortion %.1e "
        "(whole record's own rounding: type A %.1e, noise %.1e); nonlinear fit: %d / %d bins, "
        "p %.3g / %.3g, model p %.3g / %.3g, found %s / %s; wall batches / whole %.2f "
        "(%.1f s / %.1f s)",
        periods,
        _relative(f.response, e.response),
        _relative(f.relative_type_a, e.relative_type_a),
        _relative(f.phase_type_a_rad, e.phase_type_a_rad),
        _relative(f.dut_noise_v, e.dut_noise_v),
        _relative(f.dut_distortion + 1e-300, e.dut_distortion + 1e-300),
        round_a,
        round_noise,
        w.tested_bins,
        s.tested_bins,
        w.p_value,
        s.p_value,
        w.model_p_value,
        s.model_p_value,
        w.found,
        s.found,
        (t2 - t1) / (t1 - t0),
        t2 - t1,
        t1 - t0,
    )


def main(argv: list[str]) -> int:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        counts = (
            [20] if argv[1:] == ["--smoke"] else [int(a) for a in argv[1:]] or [10, 20, 40, 300]
        )
    except ValueError:
        log.error("usage: %s [P ...] | --smoke  (P: whole numbers of periods)", Path(argv[0]).name)
        return 2
    if min(counts) < 1:
        log.error("P: at least 1 period")
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "ACCELCAL_DATA_DIR": str(Path(tmp) / "data")}
        path = Path(tmp) / "piezo.h5"
        command = ["simulate", "--dut", "piezo", "--periods", str(max(counts)), "--out", str(path)]
        subprocess.run(
            [sys.executable, "-m", "app", *command],
            check=True,
            capture_output=True,
            env=env,
            cwd=ROOT,
        )
        log.info("load average %s", " ".join(f"{v:.2f}" for v in os.getloadavg()))
        for periods in counts:
            compare(path, periods)
        log.info("load average %s", " ".join(f"{v:.2f}" for v in os.getloadavg()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
