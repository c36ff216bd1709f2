"""The web view's command-line options, shared by `python -m app.web` and `accelcal web`
(a light module: building the CLI parser imports nothing heavy)."""

from __future__ import annotations

import argparse
from pathlib import Path


def port(text: str) -> int:
    """A TCP port number, 1 to 65535 (argparse refuses anything else naming --port)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"must be 1 to 65535, got {value}")
    return value


def add_options(parser: argparse.ArgumentParser) -> None:
    """The web view's options (this module and `accelcal web` share them)."""
    parser.add_argument("--db", default=None, help="records database URL (else $ACCELCAL_DB)")
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on")
    parser.add_argument("--port", type=port, default=8080, help="TCP port (1 to 65535)")
    parser.add_argument(
        "--verify-url",
        default=None,
        help="the [laboratory] verify_url printed in QR codes (default: this server's /verify)",
    )
    parser.add_argument(
        "--trust",
        type=Path,
        default=None,
        help="the lab's CA certificate (PEM or DER): signatures must chain to it",
    )
    parser.add_argument(
        "--https-only",
        action="store_true",
        help="session cookie only over HTTPS (implied by --tls-cert and --proxy)",
    )
    parser.add_argument(
        "--proxy",
        default=None,
        metavar="ADDR[,ADDR...]",
        help="the TLS-terminating reverse proxy's address(es): only their X-Forwarded-For is "
        "read, and the session cookie is Secure (default: none; the header is ignored)",
    )
    parser.add_argument(
        "--tls-cert", type=Path, default=None, help="serve HTTPS with this certificate (PEM)"
    )
    parser.add_argument(
        "--tls-key", type=Path, default=None, help="the private key (PEM) of --tls-cert"
    )
