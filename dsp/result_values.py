"""Small value helpers of dsp.calibration's results: JSON- and CSV-safe numbers, stored None
back to NaN, levels in dB and wrapped phases (moved out of dsp/calibration.py, which the
architecture test keeps under 600 lines)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["_db", "_fmt", "_json_safe", "_nan", "_wrap_deg"]


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return str(value)


def _json_safe(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _nan(item: dict[str, Any]) -> dict[str, Any]:
    optional = {"iso_limit", "tolerance_verdict", "cmc_bounds", "not_stated"}
    return {k: (float("nan") if v is None and k not in optional else v) for k, v in item.items()}


def _db(sensitivity_mv_per_ms2: float) -> float:
    """Level in dB re 1 mV/(m/s^2)."""
    return 20.0 * math.log10(sensitivity_mv_per_ms2) if sensitivity_mv_per_ms2 > 0 else math.nan


def _wrap_deg(phase_deg: np.ndarray) -> np.ndarray:
    """Wrap to (-180, 180] degrees."""
    wrapped = -((-np.asarray(phase_deg) + 180.0) % 360.0 - 180.0)
    return wrapped
