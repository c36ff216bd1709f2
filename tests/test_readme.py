"""README.md as a test: every command of its indented blocks runs, in the order written, as
written, in a fresh data directory, and ends as the README says.

How the README is read (`readme_commands`):

- A command is a line of an indented block (4 spaces) whose first word is one of `PROGRAMS`
  (`accelcal`, `make`, `openssl`, `export`); prose, the layout listing and other blocks are not
  commands. A line ending in a backslash continues on the next line.
- Its comment (`  # ...` after the code, and the deeper-indented `# ...` lines right below it)
  says how it ends, in square brackets; without a bracket it ends with exit status 0:
    `[exit N]`                  exit status N, and no traceback on stderr
    `[exit N, VERDICT]`         the same, and the output's last verdict is `VERDICT: VERDICT`
                                (PASS, FAIL or INDETERMINATE; a triaxial cross channel's
                                "VERDICT: none" is none of them)
    `[hardware, exit N]`        needs a real stand: on this machine (no NI-DAQmx driver, no
                                VISA library) it fails cleanly with exit status N, no traceback
    `[server]`                  serves until stopped: started, its page fetched (HTTP 200),
                                stopped with Ctrl-C (SIGINT); its `--port` is replaced by a
                                free port so two test runs never collide
    `[not run here: REASON]`    skipped, and the reason is said (the test suite itself, a
                                window that stays open, ...)
- Placeholders: `runs/<run-id>` is the run folder that the last command printing a
  `run folder: PATH` line named (what a user copies from the screen). Nothing else is
  substituted: the README's commands are typed as a user types them (bash: quotes, a
  here-string, `$VAR`).
- `export NAME=VALUE` sets NAME for the commands after it, as in one shell session.

Where it runs: a fresh temporary folder as the working directory (with `examples` and `sim`
linked to the repository's: the README names their stand files), its own data directory
(`ACCELCAL_DATA_DIR`, XDG data, state and config homes, the log), no `ACCELCAL_DB`, this
virtual environment's `accelcal` first on PATH, Qt offscreen. So the README runs without
records until its own `accelcal db upgrade` and with them from there on (the records
walkthrough), and the first command is the GUI's headless line: opening the GUI first changes
nothing any later command accepts.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PROGRAMS = ("accelcal", "make", "openssl", "export")
RUN_FOLDER = re.compile(r"^run folder: (\S+)$", re.MULTILINE)
PLACEHOLDER = "runs/<run-id>"
MARKER = re.compile(r"\[(exit|hardware|server|not run here)([^\]]*)\]")
VERDICTS = ("PASS", "FAIL", "INDETERMINATE")
COMMAND_TIMEOUT_S = 600.0
SERVER_START_TIMEOUT_S = 60.0
GUI_HEADLESS = "accelcal gui --sim --unpaced --autorun"


class Kind(StrEnum):
    """How the README says a command is run and checked."""

    RUN = "run"  # run it, check its exit status (and verdict)
    HARDWARE = "hardware"  # needs a real stand: fails cleanly here
    SERVER = "server"  # serves until stopped
    SKIP = "skip"  # not run here (the reason is in the README)


@dataclass(frozen=True)
class Command:
    """One README command: its text (continuations joined), its line in README.md, how it
    is checked (`kind`, exit status, verdict or None; `reason` of a skip)."""

    text: str
    line: int
    kind: Kind = Kind.RUN
    exit_status: int = 0
    verdict: str | None = None
    reason: str = ""
    comment: str = field(default="", repr=False)


def _code_and_comment(line: str) -> tuple[str, str]:
    """`line` split at its comment (` #` outside quotes)."""
    quote = ""
    for i, char in enumerate(line):
        if quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (i == 0 or line[i - 1] == " "):
            return line[:i].rstrip(), line[i + 1 :].strip()
    return line.rstrip(), ""


def _expectation(comment: str, text: str, line: int) -> Command:
    """The Command of `text` as its `comment`'s bracket says (exit 0 without one)."""
    match = MARKER.search(comment)
    if match is None:
        return Command(text, line, comment=comment)
    word, rest = match.group(1), match.group(2).strip(" ,:")
    if word == "not run here":
        if not rest:
            raise ValueError(f"README.md:{line}: [not run here] needs its reason")
        return Command(text, line, Kind.SKIP, reason=rest, comment=comment)
    if word == "server":
        return Command(text, line, Kind.SERVER, comment=comment)
    kind = Kind.HARDWARE if word == "hardware" else Kind.RUN
    found = re.search(r"exit (\d+)", match.group(0))
    if found is None:
        raise ValueError(f"README.md:{line}: {match.group(0)} names no exit status")
    verdict = next((v for v in VERDICTS if re.search(rf"\b{v}\b", rest)), None)
    return Command(text, line, kind, int(found.group(1)), verdict, comment=comment)


def readme_commands(text: str) -> list[Command]:
    """The commands of README text `text`, in order (the rules: this module's docstring)."""
    commands: list[Command] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        raw = lines[i]
        words = raw.split()
        if not (raw.startswith("    ") and not raw.startswith("     ") and words):
            i += 1
            continue
        if words[0] not in PROGRAMS:
            i += 1
            continue
        start = i + 1
        code, comment = _code_and_comment(raw.strip())
        parts: list[str] = []
        comments = [comment] if comment else []
        while code.endswith("\\"):
            parts.append(code[:-1].strip())
            i += 1
            code, comment = _code_and_comment(lines[i].strip())
            if comment:
                comments.append(comment)
        parts.append(code.strip())
        i += 1
        while i < len(lines) and lines[i].startswith("     ") and lines[i].strip().startswith("#"):
            comments.append(lines[i].strip()[1:].strip())  # the comment goes on below
            i += 1
        commands.append(_expectation(" ".join(comments), " ".join(parts), start))
    return commands


def test_the_reader_joins_lines_reads_brackets_and_leaves_prose() -> None:
    text = (
        "Prose naming accelcal run, not a command.\n"
        "\n"
        "    accelcal run --sim --out runs/    # one run [exit 0, PASS]\n"
        "    accelcal show runs/<run-id> \\\n"
        "        --json                         # a stored run\n"
        "    accelcal run --stand s.toml --out runs/   # a real stand\n"
        "                                              # [hardware, exit 1]\n"
        "    make test      # [not run here: it is the test suite]\n"
        "    accelcal web --port 8080   # [server]\n"
        "    export ACCELCAL_SIGN_PASSWORD='a # b'\n"
        "    dsp/       pure numerics\n"
        "    accelcal simulate --fault x@1 --out c.h5   # aborted [exit 3]\n"
    )
    commands = readme_commands(text)
    assert [(c.text, c.line, c.kind, c.exit_status, c.verdict) for c in commands] == [
        ("accelcal run --sim --out runs/", 3, Kind.RUN, 0, "PASS"),
        ("accelcal show runs/<run-id> --json", 4, Kind.RUN, 0, None),
        ("accelcal run --stand s.toml --out runs/", 6, Kind.HARDWARE, 1, None),
        ("make test", 8, Kind.SKIP, 0, None),
        ("accelcal web --port 8080", 9, Kind.SERVER, 0, None),
        ("export ACCELCAL_SIGN_PASSWORD='a # b'", 10, Kind.RUN, 0, None),
        ("accelcal simulate --fault x@1 --out c.h5", 12, Kind.RUN, 3, None),
    ]
    assert commands[3].reason == "it is the test suite"
    with pytest.raises(ValueError, match=r"README\.md:1: .* names no exit status"):
        readme_commands("    accelcal run   # [exit]\n")
    with pytest.raises(ValueError, match="needs its reason"):
        readme_commands("    make gui   # [not run here]\n")


def test_the_readme_states_how_its_commands_end() -> None:
    """The README's own commands: the GUI's headless line first, every hardware command marked,
    every verdict-printing run with its verdict, the make targets that cannot run here
    skipped with a reason, the web view served, and a run folder before every placeholder."""
    commands = readme_commands(README.read_text(encoding="utf-8"))
    assert len(commands) >= 60
    ran = [c for c in commands if c.kind is not Kind.SKIP]
    assert ran[0].text.startswith(GUI_HEADLESS), ran[0]  # the first command run
    for command in commands:
        words = command.text.split()
        real_stand = "--stand" in words and "examples/stand-pxi6251.toml" in words
        if real_stand or words[:2] == ["accelcal", "devices"]:
            assert command.kind is Kind.HARDWARE, command
        sweep = "--levels" in words  # a sweep prints its linearity, no verdict
        if words[:2] == ["accelcal", "run"] and command.kind is Kind.RUN and not sweep:
            assert command.exit_status != 0 or command.verdict, command
        if words[0] == "make":
            assert command.kind is Kind.SKIP, command
    assert any(c.kind is Kind.SERVER and c.text.startswith("accelcal web") for c in commands)
    first_run = next(i for i, c in enumerate(commands) if " --out runs/" in f"{c.text} ")
    assert all(PLACEHOLDER not in c.text for c in commands[:first_run])
    for name in ("web", "impact", "validate", "records user add", "verify", "teds write"):
        assert any(c.text.startswith(f"accelcal {name}") for c in commands), name


def _names(requirements: list[str]) -> set[str]:
    """Canonical distribution names of requirement strings (extras and versions dropped)."""
    return {
        re.sub(r"[-_.]+", "-", re.split(r"[\s\[<>=!~;]", r.strip(), maxsplit=1)[0]).lower()
        for r in requirements
        if r.strip() and not r.lstrip().startswith(("#", "-"))
    }


def _table_names(section: str) -> set[str]:
    """The packages named in the first column of the tables of `section` (a README part)."""
    rows = [line for line in section.splitlines() if line.startswith("| ")]
    cells = [row.split("|")[1].strip() for row in rows]
    return _names([n for cell in cells if cell not in ("package",) for n in cell.split(",")])


def test_the_dependency_tables_name_every_dependency_and_the_runtime_lock_no_test_tool() -> None:
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    runtime = _names(project["dependencies"])
    tools = _names(project["optional-dependencies"]["test"])
    text = README.read_text(encoding="utf-8")
    section = text.split("## Dependencies and why", 1)[1].split("\n## ", 1)[0]
    program, tests = section.split("The tests (", 1)
    assert runtime <= _table_names(program), runtime - _table_names(program)
    assert tools <= _table_names(tests), tools - _table_names(tests)
    lock = (ROOT / "requirements.lock").read_text(encoding="utf-8").splitlines()
    locked = _names(lock)
    assert runtime <= locked, runtime - locked
    assert not (tools - runtime) & locked, (tools - runtime) & locked  # pytest, ruff, mypy ...
    test_lock = (ROOT / "requirements-test.lock").read_text(encoding="utf-8").splitlines()
    assert "-r requirements.lock" in test_lock
    assert tools - runtime <= _names(test_lock), tools - runtime - _names(test_lock)
    assert not _names(test_lock) & locked  # each pin once: the test lock adds, never repins


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def fresh_home(tmp_path: Path) -> Iterator[tuple[Path, dict[str, str]]]:
    """A working folder with `examples` linked, and an environment of its own."""
    work = tmp_path / "work"
    work.mkdir()
    (work / "examples").symlink_to(ROOT / "examples")
    (work / "sim").symlink_to(ROOT / "sim")  # the simulated stands' files (stand-triaxial.toml)
    home = tmp_path / "home"
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith(("ACCELCAL_", "XDG_", "PYTEST_")) and k != "COV_CORE_SOURCE"
    }
    env.update(
        HOME=str(home),
        ACCELCAL_DATA_DIR=str(tmp_path / "data"),
        ACCELCAL_LOG=str(tmp_path / "state" / "accelcal.log"),
        XDG_DATA_HOME=str(home / ".local" / "share"),
        XDG_STATE_HOME=str(home / ".local" / "state"),
        XDG_CONFIG_HOME=str(home / ".config"),
        XDG_CACHE_HOME=str(home / ".cache"),
        QT_QPA_PLATFORM="offscreen",
        PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
    )
    yield work, env


def _shell(command: str, work: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["bash", "-c", command],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=COMMAND_TIMEOUT_S,
        check=False,
    )


def _serve(command: str, work: Path, env: dict[str, str]) -> str:
    """Start a [server] command on a free port, fetch its page, stop it with SIGINT; what
    went wrong, or "" when it served and stopped cleanly."""
    port = _free_port()
    text = re.sub(r"--port \d+", f"--port {port}", command)
    if text == command:
        text = f"{command} --port {port}"
    server = subprocess.Popen(
        ["bash", "-c", f"exec {text}"],
        cwd=work,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + SERVER_START_TIMEOUT_S
        status = None
        while time.monotonic() < deadline and server.poll() is None:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=5) as page:
                    status = page.status
                break
            except OSError:
                time.sleep(0.2)
        if status != 200:
            server.kill()
            err = server.communicate(timeout=30)[1]
            return f"no page (status {status}, exit {server.returncode}): {err[-2000:]}"
        server.send_signal(signal.SIGINT)
        err = server.communicate(timeout=30)[1]
    finally:
        if server.poll() is None:
            server.kill()
            server.communicate(timeout=30)
    if "Traceback" in err:
        return f"traceback on stop: {err[-2000:]}"
    return ""


def _run(command: Command, work: Path, env: dict[str, str], last_run: str | None) -> str | None:
    """Run one README command as it says; returns the run folder it printed, or `last_run`.
    Fails the test naming the README line when it does not end as the README says."""
    text = command.text
    where = f"README.md:{command.line}: {text}"
    if PLACEHOLDER in text:
        assert last_run is not None, f"{where}: no run folder printed before it"
        text = text.replace(PLACEHOLDER, last_run)
    words = shlex.split(text)
    if words[0] == "export":
        name, _, value = words[1].partition("=")
        env[name] = value
        return last_run
    if command.kind is Kind.SERVER:
        problem = _serve(text, work, env)
        assert not problem, f"{where}: {problem}"
        return last_run
    done = _shell(text, work, env)
    output = done.stdout + done.stderr
    said = (
        f"{where}\nexit {done.returncode}\nstdout: {done.stdout[-3000:]}\n"
        f"stderr: {done.stderr[-3000:]}"
    )
    assert done.returncode == command.exit_status, said
    assert "Traceback" not in done.stderr, said
    if command.verdict is not None:
        verdicts = re.findall(rf"^VERDICT: ({'|'.join(VERDICTS)})\b", output, re.MULTILINE)
        assert verdicts and verdicts[-1] == command.verdict, said
    folders = RUN_FOLDER.findall(done.stdout)
    return folders[-1] if folders else last_run


@pytest.mark.long
@pytest.mark.integration
def test_every_readme_command_runs_in_order_as_written(
    fresh_home: tuple[Path, dict[str, str]],
) -> None:
    work, env = fresh_home
    commands = readme_commands(README.read_text(encoding="utf-8"))
    data = Path(env["ACCELCAL_DATA_DIR"])
    last_run: str | None = None
    skipped: list[str] = []
    for command in commands:
        if command.kind is Kind.SKIP:
            skipped.append(f"README.md:{command.line}: {command.text} ({command.reason})")
            continue
        if command.text.startswith(GUI_HEADLESS):
            assert not (data / "records.sqlite").exists()
        last_run = _run(command, work, env, last_run)
        if command.text.startswith(GUI_HEADLESS):  # a first use creates no records
            assert not (data / "records.sqlite").exists(), "the GUI created the records"
    assert (data / "records.sqlite").is_file()  # the walkthrough's `accelcal db upgrade`
    print("not run here:\n" + "\n".join(skipped))
