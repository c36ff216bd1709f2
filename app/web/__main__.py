"""`python -m app.web --db URL --host 127.0.0.1 --port N`: serve the lab's web view (uvicorn).

The session key comes from $ACCELCAL_WEB_SECRET (at least 32 characters; then sessions outlive
a restart and several workers agree), else a random one for this process.
"""

from __future__ import annotations

import argparse
import logging
import os
import secrets
import sys
from typing import NoReturn

from app.certificate.qr import QrError, check_verify_url
from app.records.db.errors import RecordsInputError
from app.web.options import add_options

SECRET_ENV = "ACCELCAL_WEB_SECRET"
MIN_SECRET_LENGTH = 32

log = logging.getLogger("app.web")


class _OneLineParser(argparse.ArgumentParser):
    """An option refused in one line on stderr ("error: ..."), exit status 2."""

    def error(self, message: str) -> NoReturn:
        print(f"error: {message}", file=sys.stderr)
        raise SystemExit(2)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = _OneLineParser(prog="python -m app.web", description=__doc__)
    add_options(parser)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Serve until interrupted; 2 (one line on stderr) for bad options or an unusable
    database."""
    try:
        args = parse_args(argv)
    except SystemExit as exc:  # --help (0) or a refused option (2, said in one line)
        return exc.code if isinstance(exc.code, int) else 2
    return serve(args)


def serve(args: argparse.Namespace) -> int:
    """Serve the web view with parsed options until interrupted; 2 (one line on stderr) for
    bad options or an unusable database."""
    try:
        if not 1 <= args.port <= 65535:
            raise ValueError(f"--port: must be 1 to 65535, got {args.port}")
        verify_url = check_verify_url(args.verify_url) if args.verify_url else None
        if args.trust is not None and not args.trust.is_file():
            raise ValueError(f"--trust: no such file {args.trust}")
        secret = os.environ.get(SECRET_ENV) or ""
        if secret and len(secret) < MIN_SECRET_LENGTH:
            raise ValueError(f"{SECRET_ENV}: shorter than {MIN_SECRET_LENGTH} characters")
        from app.web.server import WebConfig, create_app
        from app.web.store import Store, open_read_only

        engine = open_read_only(args.db)
    except (ValueError, QrError, RecordsInputError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if not secret:
        secret = secrets.token_urlsafe(32)
        log.info("web: %s not set: sessions end when this server stops", SECRET_ENV)
    config = WebConfig(
        secret_key=secret, verify_url=verify_url, https_only=args.https_only, trust=args.trust
    )
    import uvicorn

    app = create_app(Store(engine), config)
    uvicorn.run(app, host=args.host, port=args.port, server_header=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
