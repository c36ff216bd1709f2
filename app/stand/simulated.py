"""The simulated stand's catalogue as the application sees it: DUT names, their specifications
(data sheets: sensitivity in mV/(m/s^2), tolerances in % and degrees), default plan presets,
fault kinds. With open.py and app/procedure/simulate.py, the only modules of app/ that import sim.

Light: sim.models and sim.faults only (numpy); the simulated stand itself is imported by the
functions that need it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from app.stand.dut import Band, DutSpec
from sim.faults import FAULT_KINDS
from sim.models import DUT_CATALOGUE, EXCITER_CATALOGUE, DrivenHum, StandModel, plan_preset_for

if TYPE_CHECKING:
    from sim.stand import Fault, SimulatedStand

CATALOGUE: tuple[str, ...] = tuple(DUT_CATALOGUE)
EXCITERS: tuple[str, ...] = tuple(EXCITER_CATALOGUE)  # the simulated stand's exciters


def exciter_stroke_m(name: str) -> float:
    """Peak-to-peak stroke in m of the simulated exciter `name` (KeyError when unknown)."""
    return EXCITER_CATALOGUE[name].stroke_peak_to_peak_m


# The simulated catalogue's data sheets: sensitivity +-5 % of the model's nominal value at the
# reference frequency; characteristic and phase per band (capacitive: sensitivity only, its
# 200 Hz low-pass is the sensor's own and not a tolerance).
CATALOGUE_TOLERANCES: dict[str, dict[str, Any]] = {
    "piezo": {
        "sensitivity_percent": 5.0,
        "characteristic": (Band(0.5, 5000.0, 5.0),),
        "phase": (Band(5.0, 5000.0, 5.0),),
    },
    "loose": {  # the same sensor as "piezo", badly mounted
        "sensitivity_percent": 5.0,
        "characteristic": (Band(0.5, 5000.0, 5.0),),
        "phase": (Band(5.0, 5000.0, 5.0),),
    },
    "capacitive": {"sensitivity_percent": 5.0},
}

__all__ = [
    "CATALOGUE",
    "CATALOGUE_TOLERANCES",
    "EXCITERS",
    "FAULT_KINDS",
    "TRIAXIAL_DATA_SHEET",
    "DrivenHum",
    "catalogue_entries",
    "catalogue_spec",
    "exciter_stroke_m",
    "open_simulated",
    "parse_faults",
    "parse_sim_hum",
    "plan_preset_for",
    "triaxial_spec",
]


def reference_sensitivity_mv_per_ms2() -> float:
    """The simulated reference standard's nominal sensitivity, mV/(m/s^2), before its
    conditioning amplifier (the stand file's reference gain)."""
    return float(StandModel().reference.sensitivity_mv_per_ms2)


# the simulated triaxial sensor's data sheet (sim/triaxial.py's example; each axis alike, as a
# triaxial data sheet states one nominal): 10 mV/(m/s^2) +-10 %, frequency response +-10 %
# 0.5 Hz-5 kHz, phase +-10 degrees 10 Hz-5 kHz
TRIAXIAL_DATA_SHEET: dict[str, Any] = {
    "nominal_mv_per_ms2": 10.0,
    "sensitivity_percent": 10.0,
    "characteristic": (Band(0.5, 5000.0, 10.0),),
    "phase": (Band(10.0, 5000.0, 10.0),),
}


def triaxial_spec() -> DutSpec:
    """The simulated triaxial sensor's data sheet, for each of its main axes (not the
    catalogue piezo's: its axes are 9.7-10.6 mV/(m/s^2))."""
    from sim.triaxial import MASS_G

    sheet = TRIAXIAL_DATA_SHEET
    return DutSpec(
        model="simulated triaxial (sim/triaxial.py's example)",
        manufacturer="simulated",
        kind="piezoelectric, triaxial",
        description="a small IEPE cube: three axes, resonances 22-30 kHz",
        nominal_mv_per_ms2=sheet["nominal_mv_per_ms2"],
        sensitivity_percent=sheet["sensitivity_percent"],
        characteristic=sheet["characteristic"],
        phase=sheet["phase"],
        mass_g=MASS_G,
        source="data sheet of the simulated triaxial sensor",
    )


def catalogue_spec(name: str | None) -> DutSpec:
    """The specification of the catalogue DUT `name` (its data sheet, its mass, its plan
    preset); a name not in the catalogue (None too) gives an unknown DUT."""
    sensor = DUT_CATALOGUE.get(name or "")
    if sensor is None:
        return DutSpec()
    sheet = CATALOGUE_TOLERANCES.get(sensor.name)
    shape = dataclasses.replace(sensor, mount_resonance_hz=None)  # the data sheet's, not the mount

    def response(frequency_hz: float) -> float:
        return float(abs(shape.sensitivity(np.array([frequency_hz]))[0]))

    return DutSpec(
        model=f"simulated {sensor.name} ({sensor.description})",
        manufacturer="simulated",
        kind=sensor.kind,
        description=sensor.description,
        catalogue=sensor.name,
        nominal_mv_per_ms2=sensor.sensitivity_mv_per_ms2 if sheet is not None else None,
        sensitivity_percent=sheet.get("sensitivity_percent") if sheet is not None else None,
        characteristic=sheet.get("characteristic", ()) if sheet is not None else (),
        phase=sheet.get("phase", ()) if sheet is not None else (),
        mass_g=sensor.mass_g,
        preset=plan_preset_for(sensor.name),
        source=f"data sheet of the simulated {sensor.name!r} model" if sheet is not None else "",
        response=response if sheet is not None else None,
    )


def parse_sim_hum(texts: list[str] | tuple[str, ...]) -> tuple[DrivenHum, ...]:
    """--sim-hum AMPLITUDE@FREQUENCY texts as hum the simulated stand adds only while driven
    (ValueError naming the option)."""
    return tuple(DrivenHum.parse(text) for text in texts)


def parse_faults(texts: list[str] | tuple[str, ...]) -> tuple[Fault, ...]:
    """--fault KIND@SECONDS texts as faults of the simulated stand (ValueError naming the
    option)."""
    from sim.stand import Fault

    return tuple(Fault.parse(text) for text in texts)


def open_simulated(dut: str, seed: int = 0) -> SimulatedStand:
    """The simulated stand with the catalogue DUT `dut` (its TEDS, its channels), seed `seed`."""
    from sim.stand import SimulatedStand

    return SimulatedStand(dut, seed=seed)


def open_simulated_fixture(duts: Mapping[str, str], seed: int = 0) -> Any:
    """The simulated stand with the catalogue DUTs `duts` on a fixture (input channel
    "dut.<position>" -> catalogue name; sim.fixture_stand.FixtureStand, each its own TEDS)."""
    from sim.fixture_stand import FixtureStand

    return FixtureStand(duts, seed=seed)


def catalogue_entries() -> dict[str, Any]:
    """The simulated stand's exciter, reference and DUTs, as `accelcal simulate --list` shows
    them (mm, Hz, mV/(m/s^2))."""
    stand = StandModel()
    return {
        "exciter": {
            "name": stand.exciter.name,
            "suspension_resonance_hz": stand.exciter.suspension_hz,
            "axial_resonance_hz": stand.exciter.axial_resonance_hz,
            "stroke_peak_to_peak_mm": 1e3 * stand.exciter.stroke_peak_to_peak_m,
            "midband_ms2_per_v": stand.exciter.midband_ms2_per_v,
        },
        "reference": {
            "description": stand.reference.description,
            "sensitivity_mv_per_ms2": stand.reference.sensitivity_mv_per_ms2,
            "conditioning_gain": stand.reference_gain,
        },
        "duts": {
            name: {
                "description": model.description,
                "kind": model.kind,
                "sensitivity_mv_per_ms2": 0.0 if model.dead else model.sensitivity_mv_per_ms2,
            }
            for name, model in DUT_CATALOGUE.items()
        },
    }
