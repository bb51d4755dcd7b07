"""Exceptions that carry the user-facing message and the process exit code.

`ConfigError` (exit 2) names the file and the key path; `SolverError` (exit 1) names the analysis,
the step, the residual and the DOF or model item at fault; `OutputError` (exit 2) covers result
files that cannot be written as asked (a different configuration without --force, for example).
"""

from __future__ import annotations


class BeltdynError(Exception):
    """Base class: `str(err)` is a complete one-line message for the console."""

    exit_code = 1


class ConfigError(BeltdynError):
    """Bad drive description or usage: names the file and the key path."""

    exit_code = 2

    def __init__(self, message: str, *, file: str = "", key: str = "") -> None:
        self.file = file
        self.key = key
        self.detail = message
        where = ": ".join(p for p in (file, key) if p)
        super().__init__(f"{where}: {message}" if where else message)


class OutputError(BeltdynError):
    """A results file cannot be written as asked."""

    exit_code = 2


class SolverError(BeltdynError):
    """A solver failed: names the analysis, the step, the residual and the DOF/item at fault."""

    exit_code = 1

    def __init__(
        self,
        message: str,
        *,
        analysis: str,
        step: str = "",
        residual: float | None = None,
        item: str = "",
    ) -> None:
        self.analysis = analysis
        self.step = step
        self.residual = residual
        self.item = item
        parts = [f"{analysis}: {message}"]
        if step:
            parts.append(f"at {step}")
        if residual is not None:
            parts.append(f"residual {residual:.3e}")
        if item:
            parts.append(f"at fault: {item}")
        super().__init__("; ".join(parts))


class Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C (results so far kept, partial writes discarded); exit 143."""
