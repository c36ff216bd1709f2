"""`python -m app` and the `accelcal` console script.

The whole CLI, imports included, runs inside `run()`, so a Ctrl-C in the first seconds (heavy
imports, opening the stand) ends with one line and exit 130, never a traceback. SIGXFSZ is
ignored so a file-size limit (RLIMIT_FSIZE) gives EFBIG on write, which a run turns into an
aborted "disk full" run, instead of killing the process with the drive on.
"""

from __future__ import annotations

import signal
import sys

EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports it


def run(argv: list[str] | None = None) -> int:
    """The CLI's exit code (see `app.cli.main`); 130 when interrupted by Ctrl-C."""
    try:
        if hasattr(signal, "SIGXFSZ"):
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        from app.cli import main

        return main(argv)
    except KeyboardInterrupt:
        try:
            sys.stderr.write("accelcal: interrupted (Ctrl-C)\n")
            sys.stderr.flush()
        except (OSError, ValueError):
            pass
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    raise SystemExit(run())
