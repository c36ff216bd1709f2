"""A simulated stand file whose reference standard states its own table, as a laboratory's
stand file does: the reference rule (app.procedure.reference) holds it to the records like a
real stand's, so the tests of the rule's refusals and overrides run on the simulator. (The
built-in stand's reference, with no table, is the simulator's own and exempt while it is not on
record: docs/records.md.)"""

from __future__ import annotations

from pathlib import Path

SIM_STAND = Path(__file__).resolve().parents[1] / "sim" / "stand.toml"
ANCHOR = "gain = 10.0\n"  # the last key of the built-in stand's [reference] table


def lab_stand_file(folder: Path, seed: int = 0) -> Path:
    """`folder`/lab-stand.toml: the built-in simulated stand with its reference's table (Hz,
    mV/(m/s^2), deg) stated, the one the simulator draws for `seed`."""
    from sim.stand import SimulatedStand

    chain = SimulatedStand("piezo", seed=seed).reference_chain()

    def array(values: object) -> str:
        return "[" + ", ".join(repr(float(v)) for v in values) + "]"  # type: ignore[attr-defined]

    table = (
        f"frequencies_hz = {array(chain.frequencies_hz)}\n"
        f"sensitivity_mv_per_ms2 = {array(chain.sensitivity_mv_per_ms2)}\n"
        f"phase_deg = {array(chain.phase_deg)}\n"
    )
    text = SIM_STAND.read_text(encoding="utf-8")
    assert text.count(ANCHOR) == 1, "sim/stand.toml's [reference] changed: update ANCHOR"
    path = folder / "lab-stand.toml"
    path.write_text(text.replace(ANCHOR, ANCHOR + table), encoding="utf-8")
    return path
