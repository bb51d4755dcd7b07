"""Command-line interface: wires config -> pipeline -> results file and owns the console.

A package of modules of one job each: `main` (the typer app and `run`, the console script), `commands`
(one module per command: parse options, call the pipeline, hand the results to the writer and the
console), `job` (a command's configuration, output and groups), `console` and `tables` (everything
printed), `failures` (exit codes, one-line errors) and `signals` (Ctrl-C, SIGTERM).

Exit codes: 0 ok, 1 solver failure, I/O failure or internal error, 2 bad config or usage, 130
interrupted (Ctrl-C), 143 terminated (SIGTERM). Heavy modules are imported inside the commands so that
`beltdyn --help` starts fast.
"""

from __future__ import annotations

import os

# Small dense matrices are solved fastest single-threaded; users can still override.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from beltdyn.cli.main import app, run  # noqa: E402

__all__ = ["app", "run"]
