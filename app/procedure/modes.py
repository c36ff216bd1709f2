"""The procedure's modes (CLI choices, GUI list, settings, certificate), importable light: the
`Mode` StrEnum (its home: app.io.vocabulary) and its members as the old constant names."""

from app.io.vocabulary import Mode

MODES = tuple(m.value for m in Mode)  # plain strings: argparse quotes choices by repr()
MODE_MULTISINE = Mode.MULTISINE  # old names of the members, kept for one release
MODE_STEPPED_SINE = Mode.STEPPED_SINE

__all__ = ["MODES", "MODE_MULTISINE", "MODE_STEPPED_SINE", "Mode"]
