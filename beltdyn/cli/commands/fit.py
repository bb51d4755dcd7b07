"""`beltdyn fit`: identify drive parameters from measured natural frequencies."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from beltdyn.cli.console import console, one_line
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job
from beltdyn.cli.options import ConfigArg, ForceOpt, OutOpt, SetOpt, UnsetOpt, overrides


def fit(config: Path = ConfigArg, measured: Path = typer.Option(..., "--measured", help="CSV of measured frequencies "
                                                                "(frequency [, kind, order, span, weight, scatter, "
                                                                "reference, dotted load-case keys])."),
        param: List[str] = typer.Option(..., "--param", help="A parameter to identify: KEY or KEY=LOW:HIGH.",
                                        metavar="KEY[=LOW:HIGH]"),
        output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt, unset: Optional[List[str]] = UnsetOpt,
        force: bool = ForceOpt,
        write_config: Optional[Path] = typer.Option(None, "--write-config",
                                                    help="Write the fitted configuration (TOML) here.")) -> None:
    """Identify drive parameters from measured natural frequencies (bounded least squares on the
    relative frequency errors; sensitivities from the eigenvectors): fitted values, standard
    deviations, correlations, measured against computed before and after (/fit)."""

    def body() -> None:
        from beltdyn.config import resolved_toml
        from beltdyn.results.fit import fit_group
        from beltdyn.study.fit import fit as identify, fitted_config, parse_parameter
        from beltdyn.study.measured import read_measured

        job = Job(config, output, overrides(set_, unset), force)
        data = read_measured(measured)
        params = [parse_parameter(job.cfg, p) for p in param]
        res = identify(job.cfg, data, params)
        job.add(fit_group(res))
        job.write()
        con = console()
        for w in res.warnings:
            con.print(f"[bold yellow]warning[/]: {one_line(w)}")
        print_fit(con, res, measured)
        if write_config is not None:
            write_config.parent.mkdir(parents=True, exist_ok=True)
            write_config.write_text(resolved_toml(fitted_config(job.cfg, res)), encoding="utf-8")
            con.print(f"wrote the fitted configuration to {write_config}")
        con.print(f"wrote [bold]/fit[/] to {job.output}")

    guarded(body)


def print_fit(con, res, measured: Path) -> None:
    """The identified parameters and the measured rows against the computed ones, before and after."""
    from rich.table import Table

    t = Table(title=f"identified parameters ({res.evaluations} analyses; {res.status})")
    for col in ("parameter", "initial", "fitted", "std. dev.", "rel. std. dev.", "method"):
        t.add_column(col, justify="left" if col in ("parameter", "method") else "right")
    for k, p0, p, sd, ok, how in zip(res.keys, res.initial, res.fitted, res.std, res.identifiable, res.method):
        t.add_row(k, f"{p0:.6g}", f"{p:.6g}" if ok else "not identifiable", f"{sd:.3g}" if ok else "-",
                  f"{sd / abs(p):.2%}" if ok and p else "-", how)
    con.print(t)
    ref = bool((res.reference == res.reference).any())
    t = Table(title=f"measured against computed ({measured})")
    for col in ("row", "case", "mode", "measured (Hz)") + (("reference (Hz)",) if ref else ()) + \
            ("before (Hz)", "error", "after (Hz)", "error"):
        t.add_column(col, justify="left" if col in ("case", "mode") else "right")
    for k in range(len(res.measured)):
        fm = res.measured[k]
        t.add_row(str(res.row_line[k]), res.cases[int(res.case[k])], res.mode_label[k], f"{fm:.5g}",
                  *((f"{res.reference[k]:.5g}" if res.reference[k] == res.reference[k] else "-",) if ref else ()),
                  f"{res.before[k]:.5g}", f"{(res.before[k] - fm) / fm:+.2%}", f"{res.after[k]:.5g}",
                  f"{(res.after[k] - fm) / fm:+.2%}")
    con.print(t)
    extra = ""
    if ref:
        have = res.reference == res.reference
        e = (res.reference[have] - res.measured[have]) / res.measured[have]
        extra = f" (reference column: {float((e @ e / len(e)) ** 0.5):.3%})"
    con.print(f"RMS relative error: before {res.rms_before:.3%}, after {res.rms_after:.3%}{extra}")


def register(app: typer.Typer) -> None:
    app.command()(fit)
