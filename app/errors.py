"""The one refusal base: bad input (an option, a field, a file, a plan) is refused with a
one-line message naming the field and the reason; the CLI maps every refusal to exit 2.

dsp/ and hardware/ cannot import app/: their own bases (dsp.errors.InputRefused,
hardware.errors.InputRefused) are refusals too, and REFUSALS holds all three.
"""

from __future__ import annotations

from dsp.errors import InputRefused as DspInputRefused
from hardware.errors import InputRefused as HardwareInputRefused


class Refusal(ValueError):
    """Bad input, refused before anything is done with it; the message names the field."""


#: Every refusal, whatever its package: `except REFUSALS` catches bad input (exit 2).
REFUSALS: tuple[type[ValueError], ...] = (Refusal, DspInputRefused, HardwareInputRefused)


def is_refusal(exc: BaseException) -> bool:
    """Whether `exc` is a refusal of bad input (of any package)."""
    return isinstance(exc, REFUSALS)
