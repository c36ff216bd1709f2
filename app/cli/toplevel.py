"""The top of `accelcal`'s argument parser, light: the parser class, --version, --verbose.

app.cli.parser builds every command on it; a records command is parsed by the records
commands alone on it (app.cli.main), so that listing customers imports neither numpy nor the
plans (issue 34)."""

from __future__ import annotations

import argparse
import re
import sys

NEGATIVE_NUMBER = re.compile(r"^-\.?\d")
# the records commands' names, known before any parser is built (app.cli parses a command of
# these with the records commands alone, and any other without importing them);
# app.cli.records.add_commands returns exactly these
RECORDS_COMMAND_NAMES = frozenset(
    ("db", "customers", "models", "sensors", "refs", "due", "history", "register", "control")
)
PROG = "accelcal"
DESCRIPTION = "Accelerometer calibration by comparison, multisine excitation."


class Parser(argparse.ArgumentParser):
    """ArgumentParser that takes an argument starting with a minus and a digit as a value, never
    an option: a negative number in any float notation (-2e-06, -.5, -1.5E3) or a list that
    starts with one (-10,160); argparse's own rule misses the exponent form and lists. No
    option of this program starts with a digit."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self._negative_number_matcher = NEGATIVE_NUMBER


class Version(argparse.Action):
    """--version: the version (which asks git) is looked up only when asked for, not at every
    start-up."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: object) -> None:
        kwargs.pop("default", None)
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)  # type: ignore[arg-type]

    def __call__(self, parser, namespace, values, option_string=None) -> None:  # type: ignore[no-untyped-def]
        from app.version import software_version

        parser._print_message(f"accelcal {software_version()}\n", sys.stdout)
        parser.exit()


def top_parser() -> tuple[Parser, argparse._SubParsersAction]:  # type: ignore[type-arg]
    """`accelcal` with its global options, and the subparsers the commands are added to."""
    parser = Parser(prog=PROG, description=DESCRIPTION)
    parser.add_argument("--version", action=Version, help="show the version and exit")
    parser.add_argument(
        "--verbose",
        action="store_true",
        help="also show what a run writes to its run.log, and information messages, on stderr",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    return parser, sub


def command_word(argv: list[str]) -> str | None:
    """The command named in `argv` (its first word that is not a global option), or None."""
    for word in argv:
        if word == "--":
            return None
        if not word.startswith("-"):
            return word
    return None
