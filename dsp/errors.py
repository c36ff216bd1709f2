"""The numerics' refusal base (dsp imports nothing of app): a plan, segments or an analysis
that cannot be done as asked; the application treats it as bad input (app.errors.REFUSALS)."""

from __future__ import annotations


class InputRefused(ValueError):
    """Bad input to the numerics; the message names the field and the reason."""
