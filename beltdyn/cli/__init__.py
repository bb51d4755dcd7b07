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

import gc  # noqa: E402

__all__ = ["app", "run"]

# The console script's first-generation threshold of the cyclic garbage collector (`run`): net new
# container objects between two young collections (Python's default: 700).
GC_YOUNG = 1_000_000


def run() -> None:
    """The `beltdyn` console script: the collector's young threshold raised to GC_YOUNG, then the
    app (`beltdyn.cli.main.run`: the command, then a quick exit).

    A command's start-up (typer, numpy, scipy, numba and its target context, h5py, rich and the model)
    grows the heap by some 10^5-10^6 long-lived container objects and makes almost no cyclic garbage.
    With Python's 700 it triggered hundreds of young collections that traverse them; with 200 000, set
    once `beltdyn.cli.main` was imported, 25 collections (22 while typer and rich import, one of them
    inside numba's first cache load) took 80-130 ms of process time of a short `beltdyn transient`
    (measured with `gc.callbacks`); with 1 000 000, set before anything is imported, none. A long run
    still collects, every GC_YOUNG net new containers. Set here, in the console script only: importing
    beltdyn (a test, a notebook, `beltdyn.cli.main`) leaves the collector as it is
    until `run` is called."""
    gc.set_threshold(GC_YOUNG, *gc.get_threshold()[1:])
    from beltdyn.cli.main import run as run_app

    run_app()


def __getattr__(name: str):
    """`beltdyn.cli.app`, the typer app, imported when first asked for (`run` sets the collector's
    threshold before the app's imports)."""
    if name == "app":
        from beltdyn.cli.main import app

        return app
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
