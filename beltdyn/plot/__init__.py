"""`beltdyn plot`: the figures engineers look at, drawn from a results file (HDF5) alone.

Figures (each a function returning a matplotlib Figure; `figure(kind, res)` dispatches):
- layout (`drive`): pulleys (names, radii, driver, backside idlers, tensioner arms and pivots), their
  wraps, the belt through its elements' shape functions, tangent points, hub-load arrows to scale;
- modes (`modes`): mode shapes on the drive at its static equilibrium, through the same shape
  functions, with frequency, label and the drawing scale (the paper's Fig. 4);
- sweep (`sweep`): tracked frequencies against the swept parameter (the paper's Fig. 3b); a Campbell
  diagram (every engine order labelled, the crossings) when the key is a speed; a static sweep's
  quantities (the tensioner's working curve);
- transient (`series`): histories and the amplitude spectrum with its peaks;
- response (`series`): amplitude against the driver speed, per engine order.

matplotlib is imported by this package only (the `plot` extra), so the other commands never pay for
it. The style (`style`): SI units on every axis, Okabe-Ito colours with markers and line styles so that
no two curves of a panel look alike, texts moved apart so that none overlaps another, and a corner tag
(what the figure shows, the configuration's title, the version) placed by the layout engine. Plotted
data are the file's data (the tests read them back from the figure's artists).
"""

from __future__ import annotations

from pathlib import Path

from beltdyn.plot.data import (
    KINDS,
    NEEDS,
    Results,
    available,
    figure_paths,
    parse_modes,
    read_results,
    require,
    warnings_of,
)
from beltdyn.plot.drive import hermite_curves, plot_layout
from beltdyn.plot.fit import add_measured, fit_summary, plot_fit
from beltdyn.plot.modes import plot_modes
from beltdyn.plot.series import plot_response, plot_transient
from beltdyn.plot.style import (
    OKABE_ITO,
    alike_curves,
    overlapping_texts,
    set_interactive,
    settle,
    sign,
)
from beltdyn.plot.sweep import crossings, plot_sweep, sweep_range

__all__ = ["KINDS", "NEEDS", "OKABE_ITO", "Results", "alike_curves", "available", "crossings", "figure",
           "figure_paths", "hermite_curves", "overlapping_texts", "parse_modes", "read_results", "require",
           "save", "set_interactive", "warnings_of"]

TITLES = {"layout": "drive layout", "modes": "mode shapes", "sweep": "sweep", "transient": "transient response",
          "response": "steady forced response", "fit": "fit to measured frequencies"}


def figure(kind: str, res: Results, *, modes: tuple[int, ...] | None = None, measured: Path | None = None):
    """The figure `kind` of the results (a matplotlib Figure), with its corner tag; `measured` (a
    measured-frequency CSV of `beltdyn fit`) draws its rows over a sweep figure."""
    require(res, kind)
    fig = {"layout": plot_layout, "modes": lambda r: plot_modes(r, modes), "sweep": plot_sweep,
           "transient": plot_transient, "response": plot_response, "fit": plot_fit}[kind](res)
    if measured is not None and kind == "sweep":
        add_measured(fig, res, measured)
    sign(fig, corner_tag(kind, res))
    settle(fig)  # positions final before anyone measures or saves it
    return fig


def corner_tag(kind: str, res: Results) -> str:
    """What the figure shows, of which configuration, by which beltdyn: a swept figure names the sweep
    (its configuration's title is the base case's)."""
    version = f"beltdyn {res.attrs.get('beltdyn_version', '')}".strip()
    if kind == "sweep":
        return f"{TITLES[kind]}: {sweep_range(res)}; base case: {res.title} | {version}"
    if kind == "fit":
        return f"{TITLES[kind]}: {fit_summary(res)} | {res.title} | {version}"
    return f"{TITLES[kind]} | {res.title} | {version}"


def save(fig, path: Path) -> None:
    """Write the figure (format from the suffix) through a temporary file renamed into place: an
    interrupted run leaves no half-written figure."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp{path.suffix}")
    fig.savefig(tmp)
    tmp.replace(path)
