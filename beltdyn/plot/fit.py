"""The figures of `beltdyn fit` (matplotlib through the plot package's style):

- `plot_fit`: /fit's measured frequencies against the computed ones before and after the fit (left:
  computed over measured with the line of equality; right: each row's relative error before and
  after), with the RMS relative errors and the identified parameters in the title;
- `add_measured`: the measured rows of a measured-frequency CSV drawn over a sweep figure (the
  tracked frequencies against the swept key: the paper's Fig. 3b with its experimental points), each
  at its load case's value of the swept key (the sweep's configuration value for a row that does not
  give it).

Plotted data are the files' data, unchanged (the tests read them back from the artists' gid).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from beltdyn.errors import ConfigError
from beltdyn.plot.data import Results, swept_parameter
from beltdyn.plot.style import OKABE_ITO, pyplot


def plot_fit(res: Results):
    """Measured against computed, before and after (module docstring)."""
    plt = pyplot()
    g = res.groups["fit"]
    v = g["variables"]
    fm = np.asarray(v["measured_frequency"], dtype=float)
    before = np.asarray(v["frequency_before"], dtype=float)
    after = np.asarray(v["frequency_after"], dtype=float)
    labels = [str(s) for s in v["mode_label"]]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(9.0, 4.4), layout="constrained")
    top = float(max(fm.max(), before.max(), after.max())) * 1.05
    ax.plot([0.0, top], [0.0, top], "-", color="0.6", lw=0.8, gid="equality")
    ax.plot(fm, before, "o", color=OKABE_ITO[1], mfc="none", ms=5, label="before", gid="before")
    ax.plot(fm, after, "o", color=OKABE_ITO[0], ms=3.5, label="after", gid="after")
    ax.set_xlim(0.0, top)
    ax.set_ylim(0.0, top)
    ax.set_xlabel("measured frequency (Hz)")
    ax.set_ylabel("computed frequency (Hz)")
    ax.legend(fontsize=7)
    rows = np.arange(len(fm))
    bx.bar(rows - 0.2, 100 * (before - fm) / fm, 0.4, color=OKABE_ITO[1], label="before", gid="error before")
    bx.bar(rows + 0.2, 100 * (after - fm) / fm, 0.4, color=OKABE_ITO[0], label="after", gid="error after")
    bx.axhline(0.0, color="0.3", lw=0.8)
    cases = [str(c) for c in v["load_case"]]
    several = len(set(cases)) > 1
    bx.set_xticks(rows, [lab.split(",")[0] + (f" ({c.split('=')[-1]})" if several else "")
                         for lab, c in zip(labels, cases)], rotation=60, ha="right", fontsize=6)
    bx.set_ylabel("relative error (%)")
    bx.set_title("(computed - measured) / measured" + (" per row (load case)" if several else " per row"))
    bx.legend(fontsize=7)
    ax.set_title(f"RMS relative error {100 * g['attrs']['rms_relative_error_before']:.3g} % before, "
                 f"{100 * g['attrs']['rms_relative_error_after']:.3g} % after", fontsize=7)
    return fig


def fit_summary(res: Results) -> str:
    """The identified values with their standard deviations (for the corner tag)."""
    g = res.groups["fit"]
    v = g["variables"]
    keys = [str(k) for k in g["coords"]["parameter"]]
    ok = np.asarray(v["identifiable"]).astype(bool)
    return ", ".join(f"{k} = {x:.4g} +- {s:.2g}" for k, x, s, o in
                     zip(keys, np.asarray(v["fitted"]), np.asarray(v["standard_deviation"]), ok) if o)


def measured_positions(res: Results, measured: Path) -> tuple[np.ndarray, np.ndarray, str]:
    """(x (m,), frequency (m,), swept key) of a measured file's rows over a sweep's swept key: a row's
    own value of the key (its load case), else the sweep configuration's."""
    from beltdyn.config import config_from_dict
    from beltdyn.study.fit import parameter_value
    from beltdyn.study.measured import read_measured

    key = swept_parameter(res)[0]
    data = read_measured(measured)
    default = None
    x = np.empty(data.n_rows)
    for i in range(data.n_rows):
        given = [a.split("=", 1)[1] for a in data.cases[int(data.case[i])] if a.split("=", 1)[0] == key]
        if given:
            try:
                x[i] = float(given[0])
            except ValueError:
                raise ConfigError(f"must be a number to be drawn against {key}, got {given[0]!r}", file=data.file,
                                  key=f"row {int(data.line[i])}, column '{key}'") from None
        else:
            if default is None:
                default = parameter_value(config_from_dict(tomllib.loads(res.config_text), file=str(res.path)), key)
            x[i] = default
    return x, data.frequency, key


def add_measured(fig, res: Results, measured: Path) -> None:
    """The measured rows drawn over the sweep figure `fig` (module docstring)."""
    x, f, _ = measured_positions(res, measured)
    ax = fig.axes[0]
    ax.plot(x, f, "o", mfc="none", mec="black", ms=6, mew=1.2, label=f"measured ({Path(measured).name})",
            gid="measured")
    for old in list(fig.legends):  # the sweep's legend, drawn again with the measured points
        old.remove()
    fig.legend(fontsize=6, ncol=3, loc="outside lower center")


__all__ = ["add_measured", "fit_summary", "measured_positions", "plot_fit"]
