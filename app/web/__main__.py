"""`python -m app.web --db URL --host 127.0.0.1 --port N`: serve the lab's web view (uvicorn).

The key that signs the session cookie (its form token and session id) comes from
$ACCELCAL_WEB_SECRET (checked for strength at start: 32 characters or more, no repeats, about
100 bits by its own characters; else exit 2 naming it), or a random one for this process.
Sessions are kept by this server process (app.web.guard): they end when it stops. Without
--https-only, --tls-cert or --proxy the cookie is not Secure and a warning is logged.
"""

from __future__ import annotations

import argparse
import logging
import os
import secrets
import sys
from pathlib import Path
from typing import NoReturn

from app.certificate.qr import QrError, check_verify_url
from app.records.db.errors import RecordsInputError
from app.web.guard import parse_proxies, secret_problem
from app.web.options import add_options

SECRET_ENV = "ACCELCAL_WEB_SECRET"
SECRET_HINT = 'make one with: python -c "import secrets; print(secrets.token_urlsafe(32))"'

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
        proxies = parse_proxies(args.proxy) if args.proxy else ()
        tls = _tls(args.tls_cert, args.tls_key)
        secret = os.environ.get(SECRET_ENV) or ""
        problem = secret_problem(secret) if secret else None
        if problem:
            raise ValueError(f"{SECRET_ENV}: {problem}: too weak to sign sessions; {SECRET_HINT}")
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
        secret_key=secret,
        verify_url=verify_url,
        https_only=args.https_only or tls is not None,
        trust=args.trust,
        proxies=proxies,
    )
    import uvicorn

    app = create_app(Store(engine), config)
    cert, key = tls if tls else (None, None)
    # the app reads X-Forwarded-For itself, from --proxy only (uvicorn's own default trusts
    # 127.0.0.1: any local process could then claim any client address)
    uvicorn.run(
        app,
        host=args.host,
        port=args.port,
        server_header=False,
        proxy_headers=False,
        ssl_certfile=cert,
        ssl_keyfile=key,
    )
    return 0


def _tls(cert: Path | None, key: Path | None) -> tuple[str, str] | None:
    """(certificate, key) paths to serve HTTPS with, or None; ValueError naming the option
    when only one is given or a file is missing."""
    if cert is None and key is None:
        return None
    if cert is None or key is None:
        raise ValueError("--tls-cert and --tls-key: give both or neither")
    for option, path in (("--tls-cert", cert), ("--tls-key", key)):
        if not path.is_file():
            raise ValueError(f"{option}: no such file {path}")
    return str(cert), str(key)


if __name__ == "__main__":
    sys.exit(main())
