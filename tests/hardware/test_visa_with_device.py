"""Real hardware, opt-in: `pytest tests/hardware --visa-resource GPIB0::12::INSTR`."""

from __future__ import annotations

from hardware.visa_amplifiers import BK2525Amplifier


def test_the_measuring_amplifier_answers_and_reads_back_its_settings(visa_resource):
    amplifier = BK2525Amplifier(visa_resource)
    try:
        assert amplifier.identify()
        settings = amplifier.read_settings(1)
        assert settings.gain > 0 and settings.sensitivity_mv_per_ms2 > 0
        assert amplifier.recall_work()
    finally:
        amplifier.close()
