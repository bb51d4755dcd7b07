"""`beltdyn plot`: the figures of a results file."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from beltdyn.cli.console import console, print_notes
from beltdyn.cli.failures import guarded


def plot(result: Path = typer.Argument(..., help="A beltdyn results file (HDF5)."),
         what: Optional[str] = typer.Argument(None, help="layout | modes | sweep | transient | response | fit "
                                                         "[default: every figure the file holds]"),
         output: Optional[Path] = typer.Option(None, "-o", "--output",
                                               help="Figure file (.png, .svg, .pdf); without WHAT every figure "
                                                    "as <stem>_<what><suffix>: -o fig.png writes fig_layout.png, "
                                                    "fig_modes.png, ... [default: next to RESULT]"),
         modes: Optional[str] = typer.Option(None, "--modes", help="Modes to draw, e.g. 1-8 or 1,3,5 [default: 1-8]."),
         show: bool = typer.Option(False, "--show", help="Also open the figures in a window."),
         measured: Optional[Path] = typer.Option(None, "--measured", help="A measured-frequency CSV (beltdyn fit) "
                                                 "drawn over the sweep figure.")) -> None:
    """Figures of a results file: drive layout, mode shapes, frequency maps and Campbell diagrams,
    histories and spectra, forced response (needs the plot extra: pip install 'beltdyn[plot]')."""

    def body() -> None:
        from beltdyn.errors import ConfigError, OutputError

        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise ConfigError("matplotlib is not installed: pip install 'beltdyn[plot]'", file=str(result),
                              key="plot") from None
        from beltdyn import plot as P

        if what is not None and what not in P.KINDS:
            raise ConfigError(f"unknown figure {what!r}; one of {', '.join(P.KINDS)}", file=str(result), key="WHAT")
        try:
            chosen_modes = P.parse_modes(modes)
        except ValueError:
            raise ConfigError(f"--modes must be like 1-8 or 1,3,5, got {modes!r}", file=str(result),
                              key="--modes") from None
        P.set_interactive(show)
        from beltdyn.results.io import recover

        print_notes(recover(result, if_free=True))  # a killed writer's group: recovered, as by any command
        res = P.read_results(result)
        kinds = (what,) if what else P.available(res)
        if not kinds:
            raise OutputError(f"{result}: holds no group a figure is drawn from (/geometry, /modal, /sweep, "
                              f"/transient or /response)")
        written = []
        for kind, path in P.figure_paths(result, kinds, output=output, single=bool(what)).items():
            P.save(P.figure(kind, res, modes=chosen_modes, measured=measured), path)
            written.append(str(path))
        if show:
            import matplotlib.pyplot as plt

            plt.show()
        console().print("wrote " + ", ".join(written))

    guarded(body)


def register(app: typer.Typer) -> None:
    app.command()(plot)
