"""Multisine plans made off the GUI thread: one future per (preset, line list in Hz), at
1 m/s^2 per line (the phases do not depend on the level): the run request carries them
(`RunRequest.phases_rad`), so Start does not block the window. Phases come from
app.procedure.phase_store (the presets' shipped; a custom line list's optimised the first time,
about a second, then read from the data directory).
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

from app.procedure.phase_store import stored_phases
from dsp.multisine import PRESETS, Plan, make_plan, preset_plan

PlanKey = tuple[str, tuple[float, ...]]  # (preset name, line frequencies in Hz)


class PlanCache:
    """Futures of optimised plans, the presets' own started at once."""

    def __init__(self) -> None:
        self._plans: dict[PlanKey, Future[Plan]] = {}
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan")
        for name, preset in PRESETS.items():
            key = (name, tuple(preset.nominal_frequencies_hz))
            self._plans[key] = self._pool.submit(
                preset_plan, name, level_ms2=1.0, optimiser=stored_phases
            )

    def get(self, preset_name: str, lines_hz: tuple[float, ...]) -> Future[Plan] | None:
        """The future of the plan of these lines (None: never asked)."""
        return self._plans.get((preset_name, lines_hz))

    def ask(self, preset_name: str, lines_hz: tuple[float, ...]) -> Future[Plan]:
        """The future of the plan of these lines, optimising it now if it is new."""
        key = (preset_name, lines_hz)
        if key not in self._plans:
            preset = PRESETS[preset_name]
            self._plans[key] = self._pool.submit(
                make_plan,
                lines_hz,
                preset.sample_rate_hz,
                preset.period_samples,
                1.0,
                preset.reference_frequency_hz,
                optimiser=stored_phases,
            )
        return self._plans[key]

    def phases(self, preset_name: str, lines_hz: tuple[float, ...]) -> tuple[float, ...] | None:
        """The optimised phases (rad) when they are ready, else None (the run optimises)."""
        future = self.get(preset_name, lines_hz)
        if future is None or not future.done() or future.exception() is not None:
            return None
        return tuple(float(p) for p in future.result().phases_rad)

    def wait(self) -> None:
        """Block until every plan asked for is optimised (tests, screenshots)."""
        for future in list(self._plans.values()):
            future.result()

    def close(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
