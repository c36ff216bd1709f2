"""Every `accelcal analyze` example of README.md runs as written on the files in examples/
(the commands that make a file an example analyses, `accelcal simulate --out`, run first)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from app.cli import main

ROOT = Path(__file__).resolve().parents[3]
README = ROOT / "README.md"
EXAMPLES = ROOT / "examples"
MAX_EXAMPLE_BYTES = 1_000_000


def readme_commands(text: str) -> list[list[str]]:
    """The `accelcal ...` commands of the README's indented code lines, continuation lines
    (ending in a backslash) joined and comments dropped, as argument lists."""
    commands: list[list[str]] = []
    pending = ""
    for line in text.splitlines():
        if not (line.startswith("    ") or pending):
            continue
        stripped = line.strip()
        if not pending and not stripped.startswith("accelcal "):
            continue
        code = stripped.split(" #", 1)[0].rstrip()
        if code.endswith("\\"):
            pending += code[:-1] + " "
            continue
        commands.append(shlex.split(pending + code)[1:])
        pending = ""
    return commands


def analyze_examples() -> list[list[str]]:
    """The README's analyze commands, each after the simulate commands that precede it."""
    selected: list[list[str]] = []
    for argv in readme_commands(README.read_text(encoding="utf-8")):
        if argv[0] == "analyze" or (argv[0] == "simulate" and "--out" in argv):
            selected.append(argv)
    return selected


def test_the_parser_finds_joined_commands_without_comments() -> None:
    text = (
        "intro accelcal analyze not-code.h5\n"
        "    accelcal analyze a.csv --x 1 \\\n"
        "        --y 'two words'       # a comment\n"
        "    accelcal show r   # shown\n"
        "    make gui\n"
    )
    assert readme_commands(text) == [
        ["analyze", "a.csv", "--x", "1", "--y", "two words"],
        ["show", "r"],
    ]


def test_the_readme_names_only_shipped_small_examples() -> None:
    text = README.read_text(encoding="utf-8")
    assert "../shared" not in text
    analyzed = [argv[1] for argv in analyze_examples() if argv[0] == "analyze"]
    assert len(analyzed) >= 7
    for kind in (".h5", ".csv", ".tdms"):
        assert any(f.startswith("examples/") and f.endswith(kind) for f in analyzed), kind
    assert any((ROOT / f / "manifest.json").is_file() for f in analyzed)  # a run folder
    for path in EXAMPLES.rglob("*"):
        if path.is_file():
            assert path.stat().st_size < MAX_EXAMPLE_BYTES, path
    assert (EXAMPLES / "recording.csv").read_text().splitlines()[1] == "# skew_s = 4e-06"


def test_every_analyze_example_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "examples").symlink_to(EXAMPLES)
    monkeypatch.chdir(tmp_path)
    examples = analyze_examples()
    assert any(argv[0] == "analyze" for argv in examples)
    for argv in examples:
        code = main(argv)
        out, err = capsys.readouterr()
        if argv[0] == "simulate":  # with --fault it exits non-zero, the recording in place
            assert (tmp_path / argv[argv.index("--out") + 1]).is_file(), err
            continue
        assert code == 0, f"accelcal {shlex.join(argv)}: exit {code}\n{err}"
        assert "Traceback" not in err and out
