"""`beltdyn info`: what a results file holds (groups, status, samples, writer, configuration, warnings);
a group left `running` by a writer that died is recovered first (`results.io.recover`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from beltdyn.cli.console import console, one_line, print_notes
from beltdyn.cli.failures import guarded

if TYPE_CHECKING:  # (the results package is imported by the command's body, as by every command's)
    from beltdyn.results.io import FileSummary, GroupState


def info(result: Path = typer.Argument(..., help="A beltdyn results file (HDF5)."),
         as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON (stdout) instead of tables.")
         ) -> None:
    """What a results file holds: its groups with their status, sample counts, writer (pid, alive) and
    warnings, and the configuration's title and hash. A group whose writer died (kill -9, a crash) is
    recovered first: marked 'interrupted' with every journaled sample, whatever configuration it had."""

    def body() -> None:
        from beltdyn.errors import OutputError
        from beltdyn.results.io import file_summary, recover

        if not result.is_file():
            raise OutputError(f"{result}: no such results file" if not result.exists() else
                              f"{result}: is not a regular file")
        print_notes(recover(result, if_free=True))  # a live writer holding the file: left alone, shown running
        summary = file_summary(result)
        if as_json:
            console().print_json(json.dumps(summary_dict(summary)))
        else:
            print_summary(summary)

    guarded(body)


def summary_dict(summary: FileSummary) -> dict:
    """A `results.read.FileSummary` as plain JSON-ready values."""
    return {
        "path": str(summary.path),
        "title": summary.title,
        "config_sha256": summary.config_sha256,
        "beltdyn_version": summary.beltdyn_version,
        "schema_version": summary.schema_version,
        "created_utc": summary.created_utc,
        "modified_utc": summary.modified_utc,
        "groups": [{"name": g.name, "status": g.status, "samples": g.samples, "error": g.error,
                    "writer": None if g.writer_pid is None else
                    {"pid": g.writer_pid, "host": g.writer_host, "alive": g.writer_alive},
                    "warnings": list(g.warnings)} for g in summary.groups],
    }


STATUS_STYLE = {"complete": "green", "running": "cyan", "interrupted": "yellow", "failed": "red"}


def writer_text(state: GroupState) -> str:
    """'pid 123 (alive)', 'pid 123 (dead)', 'pid 123 on HOST (unknown)' or '-' for a group not running."""
    if state.writer_pid is None:
        return "-"
    alive = {True: "alive", False: "dead"}.get(state.writer_alive, f"on {state.writer_host}: unknown")
    return f"pid {state.writer_pid} ({alive})"


def print_summary(summary: FileSummary) -> None:
    """The file's identity, then one row per group, then each group's warnings and errors."""
    from rich.table import Table
    from rich.text import Text

    con = console()
    con.print(Text.assemble(("results file", "bold"), f": {one_line(str(summary.path))}"))
    con.print(Text(f"configuration: {one_line(summary.title) or '(no title)'}, sha256 {summary.config_sha256}"))
    con.print(Text(f"written by beltdyn {summary.beltdyn_version} (results schema {summary.schema_version}), "
                   f"created {summary.created_utc}, modified {summary.modified_utc}"))
    tbl = Table(title="Groups")
    for column, justify in (("group", "left"), ("status", "left"), ("samples", "right"), ("writer", "left"),
                            ("warnings", "right")):
        tbl.add_column(column, justify=justify)
    for g in summary.groups:
        tbl.add_row(Text(f"/{g.name}"), Text(g.status, style=STATUS_STYLE.get(g.status, "")),
                    str(g.samples) if g.samples else "-", writer_text(g), str(len(g.warnings)))
    con.print(tbl)
    for g in summary.groups:
        if g.error:
            con.print(Text.assemble((f"/{g.name} {g.status}", "bold"), f": {one_line(g.error)}"))
        for w in g.warnings:
            con.print(Text.assemble((f"/{g.name} warning", "bold yellow"), f": {one_line(w)}"))


def register(app: typer.Typer) -> None:
    app.command()(info)
