"""Helpers for tests that run real `beltdyn` processes: start one as a user would (Ctrl-C active)
and wait for what it does."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from beltdyn.errors import OutputError
from beltdyn.results.io import group_states

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


def plain_env(*, drop: tuple[str, ...] = (), **extra: str) -> dict[str, str]:
    """The environment of a test's `beltdyn` process: this one's without forced colour (and the names in
    drop), with NO_COLOR set and the extra variables added."""
    hidden = ("FORCE_COLOR", "TTY_COMPATIBLE", "CLICOLOR_FORCE", *drop)
    env = {k: v for k, v in os.environ.items() if k not in hidden}
    env["NO_COLOR"] = "1"
    env.update(extra)
    return env


def run(*args, cwd, timeout: float = 120, env: dict[str, str] | None = None, **kw) -> subprocess.CompletedProcess:
    """`beltdyn *args` run to its end in cwd with captured text output (plain_env unless env is given)."""
    return subprocess.run([*BELTDYN, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=env or plain_env(), **kw)


def journal_samples(path: Path) -> int:
    """Rows a reader sees in the running transient's journal of the result file path (0 before it exists)."""
    try:
        state = group_states(path).get("transient")
    except OutputError:
        return 0
    return state.samples if state is not None and state.status == "running" else 0
