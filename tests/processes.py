"""Helpers for tests that run real `beltdyn` processes: start one as a user would (Ctrl-C active)
and wait for what it does."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

_SCRIPT = Path(sys.executable).parent / "beltdyn"
BELTDYN = [str(_SCRIPT)] if _SCRIPT.is_file() else [sys.executable, "-m", "beltdyn.cli"]  # the command, as installed


def _default_sigint() -> None:
    # a runner started in the background (or with nohup) passes SIGINT ignored; the CLI under test
    # must see Ctrl-C as a user would
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def popen(command: list[str], *, cwd, env: dict[str, str]) -> subprocess.Popen:
    """The command started with text pipes and the default Ctrl-C handling."""
    return subprocess.Popen(command, cwd=cwd, env=env, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=_default_sigint)


def wait_for(predicate, timeout: float = 60.0, step: float = 0.02):
    """predicate()'s first truthy value within timeout seconds (polled every step), else its last value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(step)
    return predicate()
