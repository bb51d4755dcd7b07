"""Time and speed series: the transient's histories and amplitude spectrum with its peaks, and the
steady forced response against the driver speed per engine order."""

from __future__ import annotations

import numpy as np

from beltdyn.plot.data import SLIP_CAP, Results, channel_names
from beltdyn.plot.orders import plot_waterfall, waterfall_panels
from beltdyn.plot.style import curve_style, pyplot, separate

HISTORIES = (("span_tension", "span tension (N)"), ("hub_load", "hub load magnitude (N)"),
             ("pulley_speed", "pulley speed (rad/s)"), ("arm_angle", "arm angle (rad)"),
             ("slip_margin", "slip margin (1)"), ("rotor_speed", "decoupler rotor speed (rad/s)"),
             ("decoupler_torque", "decoupler torque (N m)"))
READABLE = {"span_tension": "span tension", "hub_load": "hub load", "midspan_displacement": "mid-span displacement",
            "pulley_speed": "pulley speed", "arm_angle": "arm angle", "bearing_force": "bearing force",
            "slip_margin": "slip margin", "pulley_angle": "pulley angle"}


def readable(name: str) -> str:
    """A variable's name in words (span_tension -> span tension)."""
    return READABLE.get(name, name.replace("_", " "))


def series_style(k: int) -> dict:
    """curve_style for a dense series: markers spaced along the drawn curve (a tenth of its length
    apart, the odd curves' half-way between the even ones'), not on every sample."""
    return {**curve_style(k), "markevery": (0.03 + 0.05 * (k % 2), 0.1)}


def history_channels(g: dict, name: str, n_t: int) -> tuple[np.ndarray, list[str]]:
    """(n_t, n_channel) a history flattened over its trailing axes (a hub load as its magnitude), and
    the channels' names."""
    y = np.asarray(g["variables"][name], dtype=float)
    dims = list(g["dims"][name][1:])
    if name == "hub_load":
        y, dims = np.hypot(y[..., 0], y[..., 1]), dims[:1]
    return y.reshape(n_t, -1), channel_names(g, dims)


def shown_channels(name: str, y: np.ndarray) -> list[int]:
    """The channels a panel draws: every one with a finite sample; of slip margins only those below
    SLIP_CAP (a torque-free pulley's margin is infinite, or ~1e12)."""
    keep = []
    for c in range(y.shape[1]):
        finite = y[:, c][np.isfinite(y[:, c])]
        if not len(finite):
            continue
        if name == "slip_margin" and np.abs(finite).max() >= SLIP_CAP:
            continue
        keep.append(c)
    return keep


def plot_transient(res: Results):
    """Histories of the recorded series (one panel each) and their amplitude spectra with the peaks."""
    plt = pyplot()
    g = res.groups["transient"]
    t = np.asarray(g["coords"]["time"], dtype=float)
    shown = [(n, lab) for n, lab in HISTORIES if n in g["variables"]]
    spec = res.groups.get("transient/spectrum")
    orders = waterfall_panels(g)  # the run-up waterfall (`plot.orders`), below the spectrum
    rows = len(shown) + (1 if spec is not None else 0) + len(orders)
    fig, axes = plt.subplots(rows, 1, figsize=(7.5, 2.0 * rows + 0.6), layout="constrained", squeeze=False)
    axes = axes[:, 0]
    for ax, (name, lab) in zip(axes, shown):
        y, names = history_channels(g, name, len(t))
        keep = shown_channels(name, y)
        for i, c in enumerate(keep):
            ax.plot(t, y[:, c], lw=0.8, label=names[c], gid=f"{name} {names[c]}", **series_style(i))
        ax.set_ylabel(lab)
        ax.set_xlabel("time (s)")
        left = [names[c] for c in range(y.shape[1]) if c not in keep]
        note = f"left out (margin infinite, no torque): {', '.join(left)}" if name == "slip_margin" and left else None
        ax.set_title(readable(name), fontsize=8)
        if keep:
            ax.legend(fontsize=6, ncol=2, loc="center left", bbox_to_anchor=(1.01, 0.5), title=note,
                      title_fontsize=6)
    if spec is not None:
        plot_spectrum(axes[len(shown)], res, spec)
    if orders:
        plot_waterfall(axes[rows - len(orders):], g)
    return fig


def plot_spectrum(ax, res: Results, spec: dict) -> None:
    """The first recorded spectrum (span tension, else hub load, mid-span displacement) on a log scale,
    each distinct peak label once (at its largest amplitude), labels moved apart."""
    fr = np.asarray(spec["coords"]["frequency"], dtype=float)
    series = [k for k in ("span_tension", "hub_load", "midspan_displacement") if k in spec["variables"]]
    name = series[0] if series else next(iter(spec["variables"]))
    a = np.asarray(spec["variables"][name], dtype=float).reshape(len(fr), -1)
    names = channel_names(spec, spec["dims"][name][1:])
    for c in range(a.shape[1]):
        ax.plot(fr, a[:, c], lw=0.8, label=names[c], gid=f"spectrum {name} {names[c]}", **series_style(c))
    ax.set_yscale("log")
    ax.set_xlabel("frequency (Hz)")
    units = str(spec["units"].get(name, ""))
    ax.set_ylabel(f"{readable(name)} amplitude" + (f" ({units})" if units and units != "unknown" else ""))
    ax.set_title(f"amplitude spectrum of the {readable(name)}", fontsize=8)
    texts = []
    peaks = res.groups.get("transient/peaks")
    if peaks is not None:
        pv = peaks["variables"]
        df = float(np.median(np.diff(fr))) if len(fr) > 1 else 1.0
        best: dict[int, tuple[float, float]] = {}  # one label per resolution bin: the channels' peaks merged
        for i, s in enumerate(pv.get("series", [])):
            if str(s) != name:
                continue
            f_i, a_i = float(pv["frequency"][i]), float(pv["amplitude"][i])
            b = int(round(f_i / df))
            if b not in best or a_i > best[b][1]:
                best[b] = (f_i, a_i)
        for f_i, a_i in sorted(best.values(), key=lambda fa: -fa[1])[:8]:
            text = f"{f_i:.4g} Hz"
            texts.append(ax.annotate(text, (f_i, a_i), textcoords="offset points", xytext=(3, 3), fontsize=6,
                                     gid=f"peak {text}"))
    ax.legend(fontsize=6, ncol=2, loc="center left", bbox_to_anchor=(1.01, 0.5))
    separate(ax.figure, texts)


def plot_response(res: Results):
    """Amplitudes against the driver speed, one line per engine order: the largest span tension, the
    largest hub load and the arm angle (if any)."""
    plt = pyplot()
    g = res.groups["response"]
    v = g["variables"]
    speed = np.asarray(g["coords"]["speed"], dtype=float)
    orders = np.asarray(g["coords"]["order"], dtype=float)
    panels = [("span_tension_amplitude", "largest span tension\namplitude (N)"),
              ("hub_load_amplitude", "largest hub load\namplitude (N)")]
    if "arm_angle_amplitude" in v:
        panels.append(("arm_angle_amplitude", "arm angle\namplitude (rad)"))
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.0, 2.3 * len(panels) + 0.6), layout="constrained",
                             squeeze=False, sharex=True)
    for ax, (name, lab) in zip(axes[:, 0], panels):
        a = response_curves(v[name], name, len(speed), len(orders))
        for o, k in enumerate(orders):
            ax.plot(speed, a[:, o], lw=1.2, label=f"order {k:g}", gid=f"{name} order {k:g}", **series_style(o))
        ax.set_ylabel(lab)
        ax.set_yscale("log")
        ax.legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel("driver speed (rad/s)")
    return fig


def response_curves(a, name: str, n_speed: int, n_order: int) -> np.ndarray:
    """(speed, order) the largest amplitude over the channels (a hub load: the magnitude of its two
    components' amplitudes, at least the larger axis of its ellipse)."""
    a = np.asarray(a, dtype=float)
    if name == "hub_load_amplitude":
        a = np.hypot(a[..., 0], a[..., 1])
    return a.reshape(n_speed, n_order, -1).max(axis=2)
