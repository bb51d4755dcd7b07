"""The run-up waterfall: order amplitudes of the transient's histories against the reference pulley's
speed (/transient order_amplitude (speed, order, channel), `analysis.orders`), one panel per tracked
series, one curve per engine order: the largest amplitude over the series' channels (as `response`'s)."""

from __future__ import annotations

import numpy as np

from beltdyn.plot.style import curve_style

TRACKED = (("span_tension", "largest span tension\norder amplitude (N)"),
           ("hub_load", "largest hub load\norder amplitude (N)"),
           ("arm_angle", "arm angle\norder amplitude (rad)"),
           ("pulley_speed", "largest pulley speed\norder amplitude (rad/s)"))


def waterfall_panels(g: dict) -> list[tuple[str, str, np.ndarray]]:
    """(series, axis label, channel indices) of each tracked series with channels in the /transient group
    `g` (empty without order tracking). A hub load's channels are its x and y components: its panel shows
    the larger component's amplitude."""
    if "order_amplitude" not in g["variables"]:
        return []
    channels = [str(c) for c in g["coords"]["channel"]]
    panels = []
    for name, label in TRACKED:
        idx = np.array([i for i, c in enumerate(channels) if c.startswith(f"{name}[")], dtype=int)
        if idx.size:
            panels.append((name, label, idx))
    return panels


def plot_waterfall(axes, g: dict) -> None:
    """Draw `waterfall_panels(g)` on `axes` (one each): per order the largest amplitude over the series'
    channels against the reference speed (rad/s), with the order in the legend."""
    speed = np.asarray(g["coords"]["speed"], dtype=float)
    orders = np.asarray(g["coords"]["order"], dtype=float)
    amp = np.asarray(g["variables"]["order_amplitude"], dtype=float)
    for ax, (name, label, idx) in zip(axes, waterfall_panels(g)):
        top = amp[:, :, idx].max(axis=2)  # (speed, order)
        for k, order in enumerate(orders):
            ax.plot(speed, top[:, k], lw=0.9, label=f"order {order:g}", gid=f"order {name} {order:g}",
                    **curve_style(k))
        ax.ticklabel_format(axis="x", useOffset=False, style="plain")
        if np.ptp(speed) <= 1e-6 * np.abs(speed).max():  # constant speed: a readable span around it
            ax.set_xlim(0.98 * speed.min() - 1e-3, 1.02 * speed.max() + 1e-3)
        ax.set_xlabel("reference pulley speed (rad/s)")
        ax.set_ylabel(label, fontsize=7)
        ax.set_title(f"order tracking: {name.replace('_', ' ')}", fontsize=8)
        ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.01, 0.5))
