"""`accelcal web` (issue 27): the options of python -m app.web, bad ones exit 2."""

from __future__ import annotations

import pytest

from app.cli import build_parser, main

pytestmark = pytest.mark.integration


def test_web_takes_the_options_of_python_m_app_web() -> None:
    args = build_parser().parse_args(
        ["web", "--db", "sqlite://", "--port", "8123", "--verify-url", "https://x.example/v"]
    )
    assert (args.command, args.port, args.verify_url) == ("web", 8123, "https://x.example/v")


@pytest.mark.parametrize(
    ("options", "message"),
    [(["--port", "0"], "--port"), (["--verify-url", "ftp://x"], "verify_url")],
)
def test_web_refuses_bad_options_with_exit_2(options, message, capsys) -> None:
    assert main(["web", "--db", "sqlite://", *options]) == 2
    assert message in capsys.readouterr().err
