"""Every key a stand file may hold, per table (app.stand.config checks a stand file against
it). [[component]] entries are checked by dsp.uncertainty.Component and [simulation] by
sim.stand; an unknown key anywhere else is refused, naming the nearest known one (a typo such as
skew_seconds would otherwise silently mean the default)."""

from __future__ import annotations

_INPUT_KEYS = frozenset({"physical", "range_v", "coupling", "iepe_current_a", "terminal"})
_DAQ_KEYS = frozenset(("backend", "device", "skew_s", "skew_tolerance_s", "output", "reference"))
_DAQ_KEYS |= {"dut", "drive", "input_ranges_v", "adc_bits", "adc_linearity_lsb"}
# per table ("" is the top level)
SCHEMA: dict[str, frozenset[str]] = {
    "": frozenset(
        {
            "laboratory",
            "daq",
            "amplifiers",
            "limits",
            "reference",
            "dut_channel",
            "component",
            "simulation",
            "certificate",
            "plan",
            "cmc",
            "exciters",
            "instrument",  # [[instrument]]: checked by app.stand.instruments
            "fixture",  # [fixture] and [[fixture.position]]: several DUTs (app.stand.fixture)
        }
    ),
    # issue 36: the fixture of several DUTs; each [[fixture.position]] holds POSITION_KEYS
    "fixture": frozenset({"name", "mass_kg", "mass_limit_kg", "crosstalk_db", "position"}),
    "plan": frozenset(  # issue 26: the stand's own plan (app.procedure.planning)
        {
            "frequencies_hz",
            "sample_rate_hz",
            "period_samples",
            "reference_frequency_hz",
            "profile",
            "corner_hz",
        }
    ),
    "laboratory": frozenset({"name", "address", "country", "accreditation", "verify_url"}),
    "daq": _DAQ_KEYS,
    "daq.output": frozenset({"physical", "range_v"}),
    "daq.reference": _INPUT_KEYS,
    "daq.dut": _INPUT_KEYS,
    "daq.drive": _INPUT_KEYS,
    "amplifiers": frozenset({"measuring", "reference_channel", "power"}),
    "limits": frozenset(
        {
            "displacement_peak_to_peak_m",
            "velocity_peak_m_per_s",
            "acceleration_peak_ms2",
            "drive_peak_v",
        }
    ),
    "reference": frozenset(
        {
            "id",
            "model",
            "serial",
            "certificate_number",
            "certificate_date",
            "gain",
            "frequencies_hz",
            "sensitivity_mv_per_ms2",
            "phase_deg",
        }
    ),
    "dut_channel": frozenset({"gain"}),
    "certificate": frozenset(  # defaults of app.certificate.CertificateInfo
        {
            "customer",
            "customer_address",
            "authorised_by",
            "dut_model",
            "dut_serial",
            "dut_type",
            "temperature_c",
            "humidity_percent",
            "mounting",
            "certificate_number",
            "issue_date",
            "notes",
        }
    ),
}

# the keys of one [[fixture.position]] (checked by app.stand.fixture, naming the position)
POSITION_KEYS = frozenset(
    {
        "name",
        "physical",
        "axes",
        "distance_mm",
        "azimuth_deg",
        "mass_limit_kg",
        "relative_motion",
        "relative_motion_phase_deg",
        "skew_s",  # its input's stated sampling delay after the reference (s; multiplexed DAQ)
        "transverse_motion",  # a triaxial position's table transverse motion (issue 36 pt 3)
    }
)
