"""`beltdyn positions`: the tensioner arm's positions over the belt's life (FREE, MIN / NOMINAL / MAX belt
length, WORN, LOAD) with the spring torque, span tensions, hub loads and slip margins at each."""

from __future__ import annotations

import math
from pathlib import Path
from typing import List, Optional

import typer

from beltdyn.cli.console import console
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job
from beltdyn.cli.options import ConfigArg, ForceOpt, OutOpt, SetOpt, UnsetOpt, overrides


def positions(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
              unset: Optional[List[str]] = UnsetOpt, force: bool = ForceOpt,
              length_tolerance: Optional[float] = typer.Option(
                  None, "--length-tolerance", min=0.0,
                  help="Belt length tolerance (m): MIN / MAX are L0 -/+ it (default 0.3 % of L0)."),
              wear: Optional[float] = typer.Option(
                  None, "--wear", min=0.0, help="WORN: the belt lengthened by this fraction of L0 (default 0.01).")
              ) -> None:
    """Tensioner positions (spring mode): FREE, MIN / NOMINAL / MAX length, WORN, LOAD; the take-up used."""

    def body() -> None:
        from beltdyn.study.positions import positions_group, spring_arm, tensioner_positions

        job = Job(config, output, overrides(set_, unset), force)
        spring_arm(job.cfg)  # a drive without a spring-mode arm: refused before any work
        res = tensioner_positions(job.cfg, length_tolerance=length_tolerance, wear=wear)
        job.add(positions_group(job.cfg, res))
        job.write()
        print_positions(job.cfg, res)
        console().print(f"wrote [bold]/positions[/] to {job.output}")

    guarded(body)


def print_positions(cfg, res) -> None:
    """The positions table, the failed positions' messages and the take-up used of the arm's range."""
    import numpy as np
    from rich.table import Table

    con = console()
    arm = cfg.pulleys[res.arm_pulley]
    t = Table(title=f"Tensioner positions of arm '{arm.name}' (length tolerance {res.length_tolerance:.4g} m, "
                    f"wear {res.wear:.4g})")
    cols = ["position", "L0 (m)", "arm angle (rad)", "in range", "spring torque (N m)", "min tension (N)",
            "max tension (N)", f"|hub load {arm.name}| (N)", "min slip margin", "status"]
    for col in cols:
        t.add_column(col, justify="left" if col in ("position", "status") else "right")
    for k, name in enumerate(res.positions):
        tension = res.span_tension[k]
        margins = res.slip_margin[k][~np.isnan(res.slip_margin[k])]  # inf: no torque to transmit
        hub = float(np.hypot(*res.hub_load[k, res.arm_pulley]))
        t.add_row(name, _num(res.belt_length[k], ".6g"), _num(res.arm_angle[k], ".5f"),
                  _num(100.0 * res.range_fraction[k], ".1f", "%"), _num(res.spring_torque[k], ".4g"),
                  _num(float(np.min(tension)), ".4g"), _num(float(np.max(tension)), ".4g"), _num(hub, ".4g"),
                  _num(float(margins.min()) if margins.size else math.nan, ".3g"), res.status[k])
    con.print(t)
    for name, status, message in zip(res.positions, res.status, res.message):
        if message:
            con.print(f"{name}: {status}: {message}")
    if res.arm_range is not None:
        lo, hi = res.arm_range
        con.print(f"take-up used: {100.0 * res.take_up_used:.1f} % of the arm's range [{lo:g}, {hi:g}] rad")


def _num(x: float, fmt: str, suffix: str = "") -> str:
    return "-" if math.isnan(x) else ("inf" if math.isinf(x) else f"{x:{fmt}}{suffix}")


def register(app: typer.Typer) -> None:
    app.command()(positions)
