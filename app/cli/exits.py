"""The exit codes of `accelcal` and the one mapping of errors to them: a refusal (bad input,
app.errors.REFUSALS) exits 2, a hardware error 1, a run whose result could not be stored 3,
anything else 1 with its traceback kept in the log; `run --fail-exit` exits 4 on a completed
run whose verdict is FAIL. The statuses themselves: app.procedure.outcome.ExitStatus.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable

from app.errors import REFUSALS, Refusal
from app.procedure.errors import RunNotRecordedError
from app.procedure.outcome import ExitStatus
from hardware.errors import HardwareError

EXIT_OK: int = ExitStatus.OK
EXIT_FAILURE: int = ExitStatus.FAILURE
EXIT_BAD_INPUT: int = ExitStatus.BAD_INPUT
EXIT_ABORTED: int = ExitStatus.ABORTED
EXIT_FAIL_VERDICT: int = ExitStatus.FAIL_VERDICT
EXIT_BROKEN_PIPE = 128 + 13  # SIGPIPE: the reader of stdout went away (`| head`)


class UsageError(Refusal):
    """Bad command-line input; the message names the option."""


def run_command(handler: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """The command's exit code, its errors turned into one line and an exit code (by the
    error's kind: every refusal subclasses one of app.errors.REFUSALS)."""
    try:
        return handler(args)
    except BrokenPipeError:
        raise
    except REFUSALS as exc:
        print(f"accelcal {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except HardwareError as exc:
        print(f"accelcal {args.command}: {type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    except RunNotRecordedError as exc:
        print(f"accelcal {args.command}: {exc}", file=sys.stderr)
        return EXIT_ABORTED
    except Exception as exc:
        from app.logs import keep_traceback

        kept = keep_traceback(args.command, exc)
        where = f" (traceback in {kept})" if kept is not None else ""
        print(
            f"accelcal {args.command}: failed: {type(exc).__name__}: {exc}{where}",
            file=sys.stderr,
        )
        return EXIT_FAILURE


def silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush raises nothing."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass
