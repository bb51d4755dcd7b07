"""The README's commands, each of them, through the real CLI (issue 26, item 4).

Every `beltdyn ...` line of the README's ```sh blocks is either a synopsis (it names a placeholder in
capitals: CONFIG, RESULT.h5, KEY=SPEC, ...) or a command on the shipped files. The commands run as
written (from a temporary folder that sees the repository's `configs/`), each expecting exit 0 or the
code a trailing `# exit N` documents; a command that reads a results file another line writes (`-o`)
runs that line first. Those measured above ~10 s on the shared 2-core machine are `slow` (the default
run of this file stays under a minute: measured 2-10 s each, ~30 s in all): the transient (its first run
compiles the kernels, 1-5 min), the FEAD response (~1 min) and the figures (matplotlib, ~13 s each).
The synopses are checked against the CLI: every command has one, and every option a synopsis names is
one of that command's options (`beltdyn COMMAND --help`).
"""

from __future__ import annotations

import os
import pkgutil
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

import beltdyn.cli.commands
from beltdyn.cli.main import app

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
SLOW = {"transient", "response", "plot", "report", "paper"}  # subcommands measured above ~10 s (module docstring)
PLACEHOLDER = re.compile(r"\b[A-Z][A-Z0-9_]*\b")


def readme_lines() -> list[str]:
    """Every `beltdyn ...` line of the README's ```sh blocks, in order, continuation lines joined."""
    lines = []
    for block in re.findall(r"```sh\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.DOTALL):
        for line in block.splitlines():
            stripped = line.strip()
            if stripped.startswith("beltdyn "):
                lines.append(stripped)
            elif lines and stripped.startswith("[") and line.startswith(" "):  # a synopsis' continuation
                lines[-1] += " " + stripped
    return lines


def _split(line: str) -> tuple[list[str], int]:
    """(argv without `beltdyn`, the expected exit code: 0 or a trailing `# exit N`)."""
    code, _, comment = line.partition("#")
    match = re.search(r"\bexit (\d+)\b", comment)
    return shlex.split(code)[1:], int(match.group(1)) if match else 0


def is_synopsis(line: str) -> bool:
    """A line with an optional group `[...]` or a placeholder in capitals (CONFIG, RESULT.h5, KEY=SPEC)."""
    argv, _ = _split(line)
    return any("[" in a or PLACEHOLDER.fullmatch(a.split("=")[0].split(".")[0]) for a in argv)


COMMANDS = [line for line in readme_lines() if not is_synopsis(line)]
SYNOPSES = [line for line in readme_lines() if is_synopsis(line)]


def _beltdyn(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
           "COLUMNS": "200"}
    return subprocess.run([sys.executable, "-m", "beltdyn.cli", *argv], check=False, cwd=cwd, env=env,
                          capture_output=True, text=True)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    """A temporary folder where the README's relative paths `configs/...` are the repository's."""
    d = tmp_path_factory.mktemp("readme")
    (d / "configs").symlink_to(ROOT / "configs", target_is_directory=True)
    return d


def _output_of(argv: list[str]) -> str | None:
    for flag in ("-o", "--output"):
        if flag in argv:
            return argv[argv.index(flag) + 1]
    return None


def _run_line(line: str, cwd: Path) -> None:
    argv, code = _split(line)
    for arg in argv[1:]:  # a results file another README line writes: run that line first
        if arg.endswith(".h5") and arg != _output_of(argv) and not (cwd / arg).exists():
            producer = next((other for other in COMMANDS if _output_of(_split(other)[0]) == arg), None)
            assert producer is not None, f"README: {line!r} reads {arg}, which no README command writes"
            _run_line(producer, cwd)
    proc = _beltdyn(argv, cwd)
    assert proc.returncode == code, f"README: {line!r} exited {proc.returncode}, documented {code}:\n{proc.stderr}"
    out = _output_of(argv)
    if code == 0 and out is not None:
        assert (cwd / out).is_file(), f"README: {line!r} wrote no {out}"


def test_the_readme_has_commands_on_the_shipped_files():
    # What this file checks is not empty: runnable commands, and every line of a ```sh block is one or a synopsis.
    assert len(COMMANDS) >= 8 and SYNOPSES, (COMMANDS, SYNOPSES)
    written = {_output_of(_split(line)[0]) for line in COMMANDS}
    for line in COMMANDS:
        argv, _ = _split(line)
        named = [a for a in argv if a.startswith("configs/")]
        assert all((ROOT / a).is_file() for a in named), f"README: {line!r} names a file that is not shipped"
        assert named or any(a in written for a in argv[1:]), f"README: {line!r} reads neither a shipped file nor " \
                                                             "a file another README command writes"


@pytest.mark.parametrize("line", [pytest.param(line, id=" ".join(_split(line)[0][:2]),
                                               marks=[pytest.mark.slow] if _split(line)[0][0] in SLOW else [])
                                  for line in COMMANDS])
def test_readme_command_runs(line, workdir):
    _run_line(line, workdir)


def test_every_command_has_a_synopsis_and_its_options_exist():
    # Against the CLI itself: the command modules (one per command) and each command's --help (the app in
    # process, typer's test runner: 10 interpreters' start-up would cost ~20 s).
    commands = {m.name for m in pkgutil.iter_modules(beltdyn.cli.commands.__path__)}
    documented = {_split(line)[0][0] for line in SYNOPSES}
    assert commands <= documented, f"README: no synopsis of {sorted(commands - documented)}"
    for command in sorted(documented):
        named = {opt for line in SYNOPSES if _split(line)[0][0] == command
                 for opt in re.findall(r"(?<![\w-])(--?[a-z][\w-]*)", line.partition("#")[0])}
        result = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "200"})
        assert result.exit_code == 0, result.output
        offered = set(re.findall(r"(?<![\w-])(--?[a-z][\w-]*)", result.output))
        assert named <= offered, f"README: `beltdyn {command}` has no option {sorted(named - offered)}"
