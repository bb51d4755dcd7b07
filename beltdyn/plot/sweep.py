"""Swept results: tracked frequencies against the swept key (the paper's Fig. 3b), a Campbell diagram
with every engine order labelled and its crossings when the key is a speed, and the recorded static
quantities (a tensioner's working curve) for a static sweep."""

from __future__ import annotations

import json

import numpy as np

from beltdyn.plot.data import SLIP_CAP, Results, channel_names, swept_parameter
from beltdyn.plot.style import LINESTYLES, curve_style, pyplot, separate

STATIC_PANELS = (("arm_angle", "arm angle (rad)"), ("arm_torque", "spring torque (N m)"),
                 ("spring_torque", "spring torque (N m)"), ("slip_margin", "slip margin (1)"),
                 ("span_tension", "span tension (N)"), ("hub_load", "hub load magnitude (N)"))
ORDER_GREYS = ("0.15", "0.45", "0.65")


def sweep_range(res: Results) -> str:
    """The swept parameter in words, e.g. `tension.target 100 to 600 N (6 cases)`."""
    key, x, units = swept_parameter(res)
    return f"{key} {np.nanmin(x):.4g} to {np.nanmax(x):.4g}{' ' + units if units else ''} ({len(x)} cases)"


def is_campbell(res: Results) -> bool:
    key, _, _ = swept_parameter(res)
    return "speed" in key and res.holds("sweep", "frequency")


def engine_orders(res: Results) -> tuple[float, ...]:
    """The engine orders of a Campbell sweep: /sweep's `orders`, the crossings' orders, [running] orders."""
    g = res.groups["sweep"]
    sources = [g["attrs"].get("orders"), res.config.get("running", {}).get("orders")]
    if res.holds("sweep", "crossing_order") and len(res.var("sweep", "crossing_order")):
        sources.insert(1, sorted(set(float(v) for v in res.var("sweep", "crossing_order"))))
    for src in sources:
        if src is None:
            continue
        if isinstance(src, str):
            try:
                src = json.loads(src)
            except ValueError:
                continue
        return tuple(float(v) for v in np.atleast_1d(src))
    return (1.0, 2.0)


def crossings(x: np.ndarray, f: np.ndarray, orders, to_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Where a tracked frequency f (case, mode) meets an engine-order line k x to_hz (linear
    interpolation between cases, x ascending)."""
    cx, cf = [], []
    for k in orders:
        line = k * x * to_hz
        for m in range(f.shape[1]):
            d = f[:, m] - line
            for i in np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)[0]:
                t = d[i] / (d[i] - d[i + 1])
                xc = x[i] + t * (x[i + 1] - x[i])
                cx.append(xc)
                cf.append(k * xc * to_hz)
    return np.array(cx), np.array(cf)


def plot_sweep(res: Results):
    """Tracked frequencies against the (first) swept parameter; a Campbell diagram for a speed; the
    static quantities of a static sweep."""
    if not res.holds("sweep", "frequency"):
        return plot_static_sweep(res)
    plt = pyplot()
    g = res.groups["sweep"]
    key, x, units = swept_parameter(res)
    f = np.asarray(g["variables"]["frequency"], dtype=float)
    labels = [str(s) for s in g["variables"].get("label", [f"mode {i + 1}" for i in range(f.shape[1])])]
    order = np.argsort(x, kind="stable")
    fig, ax = plt.subplots(figsize=(7.0, 5.6), layout="constrained")
    for k in range(f.shape[1]):
        ax.plot(x[order], f[order, k], lw=1.1, label=labels[k], gid=f"mode {k + 1}", **curve_style(k))
    campbell = is_campbell(res)
    texts = []
    if campbell:
        orders = engine_orders(res)
        to_hz = (1.0 / (2 * np.pi)) if "rad" in units or "driver_speed" in key else 1.0
        top = float(np.nanmax(f)) * 1.08
        ax.set_ylim(0.0, top)
        xs = np.array([np.nanmin(x), np.nanmax(x)])
        ax.set_xlim(*xs)
        for i, k in enumerate(orders):
            ls = LINESTYLES[i % len(LINESTYLES)]
            grey = ORDER_GREYS[(i // len(LINESTYLES)) % len(ORDER_GREYS)]
            ax.plot(xs, k * xs * to_hz, linestyle=ls, color=grey, lw=1.0, gid=f"order {k:g}", label=f"_order {k:g}")
            x_end = min(xs[1], top / (k * to_hz)) if k * to_hz > 0 else xs[1]  # where the line leaves the panel
            texts.append(ax.annotate(f"order {k:g}", (x_end, k * x_end * to_hz), textcoords="offset points",
                                     xytext=(-3, -3), ha="right", va="top", fontsize=7, color=grey,
                                     gid=f"order label {k:g}",
                                     bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.85}))
        if res.holds("sweep", "crossing_frequency") and len(res.var("sweep", "crossing_frequency")):
            xname = "crossing_driver_speed" if res.holds("sweep", "crossing_driver_speed") else None
            cx = res.var("sweep", xname) if xname and "driver_speed" in key else None
            if cx is None:
                cx, cf = crossings(x[order], f[order], orders, to_hz)
            else:
                cf = res.var("sweep", "crossing_frequency")
        else:
            cx, cf = crossings(x[order], f[order], orders, to_hz)
        if len(cx):
            ax.plot(cx, cf, linestyle="None", marker="x", color="k", ms=6, mew=1.5, gid="crossings",
                    label="resonances (order crossings)")
    ax.set_xlabel(f"{key} ({units})" if units else key)
    ax.set_ylabel("natural frequency (Hz)")
    ax.set_title("Campbell diagram" if campbell else f"tracked natural frequencies against {key}")
    fig.legend(fontsize=6, ncol=3, loc="outside lower center")
    separate(fig, texts)
    return fig


def plot_static_sweep(res: Results):
    """A static (or transient) sweep's recorded quantities against the swept key, one panel each: with
    a torque swept, the tensioner's working curve (arm angle and spring torque against the torque)."""
    plt = pyplot()
    g = res.groups["sweep"]
    key, x, units = swept_parameter(res)
    order = np.argsort(x, kind="stable")
    shown = [(n, lab) for n, lab in STATIC_PANELS if n in g["variables"]
             and np.isfinite(np.asarray(g["variables"][n], dtype=float)).any()]
    fig, axes = plt.subplots(max(len(shown), 1), 1, figsize=(7.0, 2.1 * max(len(shown), 1) + 0.9),
                             layout="constrained", squeeze=False, sharex=True)
    for ax, (name, lab) in zip(axes[:, 0], shown):
        y = np.asarray(g["variables"][name], dtype=float)
        dims = list(g["dims"][name][1:])
        if name == "hub_load":
            y, dims = np.hypot(y[..., 0], y[..., 1]), dims[:1]
        y2 = y.reshape(len(x), -1)
        names = channel_names(g, dims)
        keep = [c for c in range(y2.shape[1]) if np.isfinite(y2[:, c]).any()
                and (name != "slip_margin" or np.nanmax(np.abs(y2[:, c])) < SLIP_CAP)]
        for i, c in enumerate(keep):
            ax.plot(x[order], y2[order, c], lw=1.1, label=names[c], gid=f"{name} {names[c]}", **curve_style(i))
        left = len([c for c in range(y2.shape[1]) if np.isfinite(y2[:, c]).any()]) - len(keep)
        ax.set_ylabel(lab)
        title = lab.split(" (")[0] + (f" ({left} torque-free pulleys, margin infinite, left out)" if left else "")
        ax.set_title(title, fontsize=8)
        if keep:
            ax.legend(fontsize=6, ncol=2 if len(keep) > 8 else 1, loc="center left", bbox_to_anchor=(1.01, 0.5))
    axes[-1, 0].set_xlabel(f"{key} ({units})" if units else key)
    return fig

