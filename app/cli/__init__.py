"""The `accelcal` command line: thin, it parses, calls the same code as the GUI and prints.

    toplevel.py  the parser's top (light)            exits.py     errors -> exit codes
    parser.py    the options of every command        printers.py  text output
    options.py   option types, bounds, value checks  records.py   the records commands
    readers.py   `analyze`'s recording by file type
    plan, analyze, run, show, certificate, verify, simulate, teds, devices (and gui): one
    module per command

Exit codes: 0 success, 2 bad input (options, plan, file: every app.errors refusal), 1 any
other failure, 3 a run that did not complete or whose result could not be stored.
`import app.cli` imports no command (tests/app/cli/test_startup.py): a command's module is
imported when it runs, and a records command is parsed by the records commands alone, so
that it imports neither numpy nor the plans (issue 34).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from app.cli.exits import (
    EXIT_ABORTED,
    EXIT_BAD_INPUT,
    EXIT_BROKEN_PIPE,
    EXIT_FAILURE,
    EXIT_OK,
    UsageError,
    run_command,
    silence_stdout,
)
from app.cli.toplevel import RECORDS_COMMAND_NAMES, command_word, top_parser

if TYPE_CHECKING:
    import argparse

    from app.cli.records import Handler

__all__ = [
    "COMMANDS",
    "EXIT_ABORTED",
    "EXIT_BAD_INPUT",
    "EXIT_BROKEN_PIPE",
    "EXIT_FAILURE",
    "EXIT_OK",
    "Bounded",
    "UsageError",
    "build_parser",
    "main",
    "parse_frequencies",
    "plan_report",
    "print_results",
]

# each command's handler as (module, function), imported when the command runs (a handler
# itself may stand in for one: the tests put one there)
COMMANDS: dict[str, Handler | tuple[str, str]] = {
    "plan": ("app.cli.plan", "cmd_plan"),
    "analyze": ("app.cli.analyze", "cmd_analyze"),
    "simulate": ("app.cli.simulate", "cmd_simulate"),
    "run": ("app.cli.run", "cmd_run"),
    "show": ("app.cli.show", "cmd_show"),
    "certificate": ("app.cli.certificate", "cmd_certificate"),
    "devices": ("app.cli.devices", "cmd_devices"),
    "gui": ("app.cli.devices", "cmd_gui"),
    "verify": ("app.cli.verify", "cmd_verify"),
    "teds": ("app.cli.teds", "cmd_teds"),
    "impact": ("app.cli.impact", "cmd_impact"),
    "validate": ("app.cli.validate", "cmd_validate"),
    "web": ("app.cli.web", "cmd_web"),
    "records": ("app.cli.web", "cmd_records"),
}
# the names this package exports from its modules, imported on first use
_LAZY = {
    "Bounded": "app.cli.options",
    "parse_frequencies": "app.cli.options",
    "build_parser": "app.cli.parser",
    "plan_report": "app.cli.plan",
    "print_results": "app.cli.printers",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'app.cli' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


def _handler(command: str) -> Handler:
    entry = COMMANDS[command]
    if callable(entry):
        return entry
    module, function = entry
    handler: Handler = getattr(importlib.import_module(module), function)
    return handler


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; its exit code (EXIT_*, or EXIT_BROKEN_PIPE when the reader of stdout
    went away, e.g. `accelcal plan | head`)."""
    try:
        code = _main(argv)
        sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
        return code
    except BrokenPipeError:
        silence_stdout()
        return EXIT_BROKEN_PIPE


def _parse(argv: list[str]) -> tuple[argparse.Namespace, Handler | None]:
    """The parsed arguments and, for a records command, its handler (parsed by the records
    commands alone: no plan, stand or numpy imported; `plan` by its own options alone: no
    run options, simulated stand or records commands). SystemExit from argparse passes."""
    word = command_word(argv)
    if word in RECORDS_COMMAND_NAMES:
        from app.cli.records import add_commands

        parser, sub = top_parser()
        records = add_commands(sub)
        args = parser.parse_args(argv)
        return args, records[args.command]
    if word == "plan":
        from app.cli.plan_parser import add_plan_command

        parser, sub = top_parser()
        add_plan_command(sub)
        return parser.parse_args(argv), None
    from app.cli.parser import RECORDS_COMMANDS, build_parser

    args = build_parser().parse_args(argv)
    return args, RECORDS_COMMANDS.get(args.command)


def _main(argv: Sequence[str] | None) -> int:
    words = list(sys.argv[1:] if argv is None else argv)
    try:
        args, handler = _parse(words)
    except SystemExit as exc:  # --help (0) or an option refused by argparse (2, message said)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    from app.logs import setup, teardown

    log_handler = setup(args.verbose)
    try:
        return run_command(handler or _handler(args.command), args)
    finally:
        teardown(log_handler)


if __name__ == "__main__":
    raise SystemExit(main())
