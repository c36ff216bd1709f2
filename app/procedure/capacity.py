"""What a plan and a run would take of this machine, known from the period and the sample rate
before anything is allocated, optimised or moved (issue 33 point 6): memory in bytes, the phase
optimisation's time in s. A plan or run that needs more memory than this machine can give it is
refused (`PlanError`, exit 2) naming both, so every sample rate and period the options accept is
one the program can do here, or is refused before it starts.

The figures are upper estimates: a run at 409.6 kS/s (N = 819200, 8 periods) peaked at 311 MB
(ru_maxrss) where `run_cost` says 1.2 GB; the optimiser's buffers are
dsp.crestfactor.OPTIMISER_BYTES_PER_SAMPLE per sample.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

from app.io.checks import MAX_RECORDING_SAMPLES
from dsp import crestfactor
from dsp.crestfactor import peak_grid_samples
from dsp.multisine import PlanError

log = logging.getLogger(__name__)

BASE_BYTES = 256 * 2**20  # the program and its libraries (a run at 6 kS/s peaks at 178 MB)
# per sample of a period, for every period a run holds: three channels of float64 recorded,
# read back for the analysis and their spectra (complex128) beside them
RUN_BYTES_PER_SAMPLE = 64
# background, identification, equalisation and fades beside the acquired periods (a run of 8
# periods at 6 and 102.4 kS/s recorded 18)
EXTRA_PERIODS = 12
PEAK_BYTES_PER_POINT = 40  # a predicted-peak waveform: its spectrum, the irfft and a copy
SHARE_OF_AVAILABLE = 0.5  # a run may take at most half the memory available when it starts
# CPU time of one objective evaluation per period sample: 40-47 ns measured (N = 12000 to 2e6)
SECONDS_PER_SAMPLE_EVALUATION = 50e-9
MEMINFO = Path("/proc/meminfo")


@dataclass(frozen=True)
class Cost:
    """What a plan (or a run of it) takes: memory (bytes) and the phase optimisation (s)."""

    memory_bytes: float
    optimise_s: float

    def describe(self) -> str:
        return f"about {_size(self.memory_bytes)} of memory and {self.optimise_s:.0f} s"


def plan_cost(period_samples: int, periods: int | None = None, top_bin: int = 0) -> Cost:
    """The cost of a plan of `period_samples` whose highest line is on `top_bin` (its phases
    optimised, its peaks predicted), and of running it for `periods` acquired periods (None:
    the plan only)."""
    n = int(period_samples)
    grid = peak_grid_samples(n, [max(int(top_bin), 1)])
    work = max(crestfactor.OPTIMISER_BYTES_PER_SAMPLE * n, PEAK_BYTES_PER_POINT * grid)
    memory = BASE_BYTES + work
    if periods is not None:
        held = int(periods) + EXTRA_PERIODS
        memory = max(memory, BASE_BYTES + RUN_BYTES_PER_SAMPLE * n * held)
    evaluations = crestfactor.evaluation_cap(n)
    return Cost(float(memory), evaluations * n * SECONDS_PER_SAMPLE_EVALUATION)


def available_memory_bytes() -> float:
    """Memory this machine can give a new process now: MemAvailable (Linux), else the physical
    memory; inf when neither is known."""
    try:
        for line in MEMINFO.read_text(encoding="ascii").splitlines():
            if line.startswith("MemAvailable:"):
                return float(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return float("inf")


def check_capacity(
    period_samples: int,
    sample_rate_hz: float,
    *,
    periods: int | None = None,
    top_bin: int = 0,
    available_bytes: float | None = None,
) -> Cost:
    """The cost of the plan (and of a run of `periods`), or PlanError naming the period, the
    rate, the memory it needs and what this machine can give it, before anything is
    allocated."""
    cost = plan_cost(period_samples, periods, top_bin)
    if periods is not None:
        samples = (int(periods) + EXTRA_PERIODS) * int(period_samples)
        if samples > MAX_RECORDING_SAMPLES:
            raise PlanError(
                [
                    f"periods: a run of {periods} periods of {period_samples} samples at "
                    f"{sample_rate_hz:g} Hz records about {samples} samples a channel, more "
                    f"than a recording may hold ({MAX_RECORDING_SAMPLES}; analyze and verify "
                    "could not read it back): lower --periods, --sample-rate or --period"
                ]
            )
    available = available_memory_bytes() if available_bytes is None else available_bytes
    limit = SHARE_OF_AVAILABLE * available
    if cost.memory_bytes > limit:
        what = f"a run of {periods} periods" if periods is not None else "the plan"
        raise PlanError(
            [
                f"period: {period_samples} samples at {sample_rate_hz:g} Hz "
                f"({period_samples / sample_rate_hz:g} s): {what} would take "
                f"{cost.describe()}; this machine can give it {_size(limit)} (half of the "
                f"{_size(available)} available now): lower --sample-rate or --period"
            ]
        )
    log.debug("plan of %d samples: %s", period_samples, cost.describe())
    return cost


def _size(n: float) -> str:
    """Bytes as MB or GB (decimal), e.g. '4.3 GB'."""
    return f"{n / 1e9:.1f} GB" if n >= 1e9 else f"{n / 1e6:.0f} MB"
