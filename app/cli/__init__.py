"""The `accelcal` command line: thin, it parses, calls the same code as the GUI and prints.

    parser.py    the options of every command        exits.py     errors -> exit codes
    options.py   option types, bounds, value checks  printers.py  text output
    readers.py   `analyze`'s recording by file type  records.py   the records commands
    plan, analyze, run, show, certificate, verify, simulate, teds, devices (and gui): one
    module per command

Exit codes: 0 success, 2 bad input (options, plan, file: every app.errors refusal), 1 any
other failure, 3 a run that did not complete or whose result could not be stored.
Only light modules are imported at start (tests/app/cli/test_startup.py); every command imports
what it uses.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from app.cli.analyze import cmd_analyze
from app.cli.certificate import cmd_certificate
from app.cli.devices import cmd_devices, cmd_gui
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
from app.cli.impact import cmd_impact
from app.cli.options import Bounded, parse_frequencies
from app.cli.parser import RECORDS_COMMANDS, build_parser
from app.cli.plan import cmd_plan, plan_report
from app.cli.printers import print_results
from app.cli.records import Handler
from app.cli.run import cmd_run
from app.cli.show import cmd_show
from app.cli.simulate import cmd_simulate
from app.cli.teds import cmd_teds
from app.cli.validate import cmd_validate
from app.cli.verify import cmd_verify
from app.cli.web import cmd_records, cmd_web

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

COMMANDS: dict[str, Handler] = {
    "plan": cmd_plan,
    "analyze": cmd_analyze,
    "simulate": cmd_simulate,
    "run": cmd_run,
    "show": cmd_show,
    "certificate": cmd_certificate,
    "devices": cmd_devices,
    "gui": cmd_gui,
    "verify": cmd_verify,
    "teds": cmd_teds,
    "impact": cmd_impact,
    "validate": cmd_validate,
    "web": cmd_web,
    "records": cmd_records,
}


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


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or an option refused by argparse (2, message said)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    from app.logs import setup, teardown

    handler = setup(args.verbose)
    try:
        return run_command((COMMANDS | RECORDS_COMMANDS)[args.command], args)
    finally:
        teardown(handler)


if __name__ == "__main__":
    raise SystemExit(main())
