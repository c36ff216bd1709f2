"""`python -m app` and the `accelcal` console script.

The whole CLI, imports included, runs inside `run()`, so a Ctrl-C in the first seconds (heavy
imports, opening the stand) ends with one line and exit 130, never a traceback. SIGXFSZ is
ignored so a file-size limit (RLIMIT_FSIZE) gives EFBIG on write, which a run turns into an
aborted "disk full" run, instead of killing the process with the drive on (CPython ignores it
at start-up already; it is set again here so an embedding interpreter cannot undo that).
"""

from __future__ import annotations

import logging
import os
import signal
import sys

EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports it


def run(argv: list[str] | None = None) -> int:
    """The CLI's exit code (see `app.cli.main`); Ctrl-C outside a run exits 130 at once."""
    try:
        if hasattr(signal, "SIGXFSZ"):
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        from app.cli import main

        return main(argv)
    except KeyboardInterrupt:
        # A KeyboardInterrupt raised inside some imports leaves CPython's "unhandled
        # KeyboardInterrupt" flag set even though it was caught here, and the interpreter would
        # then kill itself with SIGINT (exit -2) at the very end. No run is open at this point
        # (a run handles Ctrl-C itself): say it in one line, flush, and leave with 130 at once.
        for stream, text in ((sys.stdout, ""), (sys.stderr, "accelcal: interrupted (Ctrl-C)\n")):
            try:
                stream.write(text)
                stream.flush()
            except (OSError, ValueError):
                pass
        logging.shutdown()
        os._exit(EXIT_INTERRUPTED)


if __name__ == "__main__":
    raise SystemExit(run())
