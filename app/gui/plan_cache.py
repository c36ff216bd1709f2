"""Multisine plans made off the GUI thread (a custom plan's phase optimisation takes about a
second the first time; app.procedure.phase_store keeps the result): one future per phase key
(app.procedure.service.RunService.phase_key: the lines, rate, period and reference of the plan
that will run, at 1 m/s^2 per line; the phases do not depend on the level). The run service
makes each plan (`RunService.unit_plan`); this only keeps the futures, so Start does not block
the window.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor

from app.procedure.planning import PlanRequest
from dsp.multisine import Plan


class PlanCache:
    """Futures of the plans `make(key)` makes, the `first` keys started at once."""

    def __init__(self, make: Callable[[PlanRequest], Plan], first: Iterable[PlanRequest] = ()):
        self._make = make
        self._plans: dict[PlanRequest, Future[Plan]] = {}
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan")
        for key in first:
            self.ask(key)

    def get(self, key: PlanRequest) -> Future[Plan] | None:
        """The future of the plan of `key` (None: never asked)."""
        return self._plans.get(key)

    def ask(self, key: PlanRequest) -> Future[Plan]:
        """The future of the plan of `key`, made now if it is new."""
        if key not in self._plans:
            self._plans[key] = self._pool.submit(self._make, key)
        return self._plans[key]

    def ready(self, key: PlanRequest) -> Plan | None:
        """The plan of `key` when it is made, else None (the run then makes it itself)."""
        future = self.get(key)
        if future is None or not future.done() or future.exception() is not None:
            return None
        return future.result()

    def wait(self) -> None:
        """Block until every plan asked for is made (tests, screenshots); a refused plan is
        the preview's to report."""
        for future in list(self._plans.values()):
            future.exception()

    def close(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
