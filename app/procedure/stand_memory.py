"""The stand's stored response as one run uses it: recalled before equalisation (issue 14
point 1), kept once the run has completed. Wraps app.stand.response with this run's stand,
DUT mass class and plan; a store that cannot be read or written never fails the run."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np

from app.procedure.settings import RunSettings
from app.stand.open import Stand
from app.stand.response import (
    ResponseStore,
    StoredResponse,
    mass_class,
    now_utc,
    stand_sha256,
)
from dsp.multisine import Plan

log = logging.getLogger(__name__)


class StandMemory:
    """Recall and keep this stand's response for this plan and DUT mass class."""

    def __init__(
        self,
        store: ResponseStore | None,
        stand: Stand,
        plan: Plan,
        settings: RunSettings,
        log_line: Callable[[str], None],
    ):
        self.store = store
        self.plan = plan
        self.settings = settings
        self.log = log_line
        self.stand_sha256 = stand_sha256(stand.config.text or stand.config.source)
        self.realisation = stand.realisation
        self.mass_class = mass_class(settings.dut_mass_g)

    def recall(self) -> StoredResponse | None:
        """The stored response to start equalisation from, or None (said in run.log)."""
        if self.store is None:
            return None
        try:
            found = self.store.lookup(
                self.stand_sha256,
                self.realisation,
                self.settings.mode,
                self.mass_class,
                self.plan,
                now=now_utc(),
                max_age_days=self.settings.stored_response_max_age_days,
            )
        except OSError as exc:
            log.warning("stored responses unreadable: %s", exc)
            self.log(f"stand response: stored responses unreadable ({exc}); identifying")
            return None
        self.log(f"stand response: {found.reason}")
        return found.entry

    def keep(self, response: np.ndarray, worst_error: float, run_id: str | None) -> None:
        """Store the response a completed run converged with (replacing the one of its level)."""
        if self.store is None:
            return
        plan = self.plan
        entry = StoredResponse(
            stand_sha256=self.stand_sha256,
            realisation=self.realisation,
            mode=self.settings.mode,
            mass_class=self.mass_class,
            sample_rate_hz=plan.sample_rate_hz,
            period_samples=plan.period_samples,
            bins=tuple(int(b) for b in plan.bins),
            levels_ms2=tuple(float(a) for a in plan.amplitudes_ms2),
            phases_rad=tuple(float(p) for p in plan.phases_rad),
            response=np.asarray(response, complex),
            measured_utc=now_utc().isoformat(timespec="seconds"),
            run_id=run_id,
            worst_error=float(worst_error),
        )
        try:
            path = self.store.save(entry)
        except (OSError, ValueError) as exc:
            log.warning("stand response not stored: %s", exc)
            self.log(f"stand response: not stored ({exc})")
            return
        self.log(f"stand response: stored in {path}")

    def describe(self, entry: StoredResponse | None, outcome: str, **more: Any) -> dict[str, Any]:
        """What the run record says about where equalisation started."""
        described: dict[str, Any] = {
            "source": outcome,
            "stand_sha256": self.stand_sha256,
            "mass_class": self.mass_class,
        }
        if entry is not None:
            described["stored"] = entry.summary()
        described.update(more)
        return described
