"""The drive drawn: the belt through its elements' own shape functions, pulleys with their wraps,
tensioner arms, tangent points and hub-load arrows (the layout figure)."""

from __future__ import annotations

import numpy as np

from beltdyn.model.ancf import shape_functions
from beltdyn.plot.data import Results
from beltdyn.plot.style import OKABE_ITO, pyplot, separate

POINTS_PER_ELEMENT = 8  # samples of each element's cubic between its nodes
BELT = "0.1"
ARM = OKABE_ITO[3]  # reddish purple: not the hub-load arrows' vermillion
ARROW = OKABE_ITO[1]
WRAP = OKABE_ITO[2]


def hermite_curves(position: np.ndarray, slope: np.ndarray | None, span: np.ndarray,
                   element_length: np.ndarray | None, *, points: int = POINTS_PER_ELEMENT) -> dict[int, np.ndarray]:
    """span -> (n_el * points + 1, 2) the belt (or a motion of it) along each span through the ANCF
    elements' cubic shape functions (paper Eq. 3, `model.ancf.shape_functions`), `points` samples per
    element, the nodes at every `points`-th row.

    position, slope : (n_node, 2) nodal positions r and slopes r' = dr/dx (x the reference arc
        length), spans one after the other (/static node_position, node_slope; a mode's node_shape,
        node_shape_slope); without slopes the nodes joined by straight lines (files written before
        slopes were).
    span : (n_node,) 0-based span of each node; element_length : (n_span,) reference element length.
    """
    out = {}
    xi = np.arange(points) / points
    for s in np.unique(span):
        r = position[span == s]
        if slope is None or element_length is None or not element_length[s] > 0 or len(r) < 2:
            out[int(s)] = r.copy()
            continue
        d = slope[span == s]
        e = np.concatenate([r[:-1], d[:-1], r[1:], d[1:]], axis=1).reshape(-1, 4, 2)  # (n_el, 4, 2): r_i r'_i r_j r'_j
        S, _, _ = shape_functions(xi, np.full(len(e), float(element_length[s])))  # (n_el, points, 4)
        out[int(s)] = np.vstack([(S @ e).reshape(-1, 2), r[-1:]])
    return out


def belt_curves(res: Results) -> dict[int, np.ndarray]:
    """The belt at equilibrium along each span (hermite_curves of /static)."""
    g = "static"
    slope = res.var(g, "node_slope") if res.holds(g, "node_slope") else None
    length = res.var(g, "span_element_length") if res.holds(g, "span_element_length") else None
    return hermite_curves(res.var(g, "node_position"), slope, res.var(g, "node_span"), length)


def tangent_points(res: Results) -> tuple[np.ndarray, np.ndarray]:
    """(n_span, 2) start and end tangent points: the belt's end nodes at equilibrium where the span has
    nodes, else /geometry's (laid out before the static solution moved the pulleys)."""
    a, b = res.var("geometry", "span_start").copy(), res.var("geometry", "span_end").copy()
    if res.has("static") and res.holds("static", "node_position"):
        nodes, span = res.var("static", "node_position"), res.var("static", "node_span")
        for s in np.unique(span):
            a[s], b[s] = nodes[span == s][0], nodes[span == s][-1]
    return a, b


def pulley_centres(res: Results) -> np.ndarray:
    return res.var("static", "pulley_center") if res.has("static") else res.var("geometry", "pulley_center")


def pulley_names(res: Results) -> list[str]:
    return [str(x) for x in res.coord("geometry", "pulley")] if res.has("geometry") else \
        [p.get("name", f"P{i}") for i, p in enumerate(res.config.get("pulleys", []))]


def driver_index(res: Results) -> int:
    pcfg = list(res.config.get("pulleys", []))
    return next((j for j, p in enumerate(pcfg) if p.get("driver")), 0)


def wrap_arcs(centre: np.ndarray, radius: np.ndarray, start: np.ndarray, end: np.ndarray, wrap: np.ndarray,
              *, points: int = 48) -> list[np.ndarray]:
    """(points, 2) the arc of belt on each pulley j: from the end tangent point of the span arriving
    (span j - 1) to the start tangent point of the span leaving (span j), through the wrap angle, in
    whichever sense of rotation reaches the second point.

    centre, start, end : (n, 2); radius, wrap : (n,) (wrap in rad)."""
    arcs = []
    n = len(centre)
    for j in range(n):
        p, q = end[(j - 1) % n] - centre[j], start[j] - centre[j]
        a0, a1 = np.arctan2(p[1], p[0]), np.arctan2(q[1], q[0])
        miss = [abs(np.angle(np.exp(1j * (a0 + sense * wrap[j] - a1)))) for sense in (1.0, -1.0)]
        sense = 1.0 if miss[0] <= miss[1] else -1.0
        t = a0 + sense * np.linspace(0.0, wrap[j], points)
        arcs.append(centre[j] + radius[j] * np.column_stack([np.cos(t), np.sin(t)]))
    return arcs


def draw_drive(ax, res: Results, *, labels: bool = True, color: str = "0.25", belt_label: str = "belt") -> list:
    """Pulleys (at the solved centres when /static is there) with their wraps, tensioner arms and the
    belt (through the shape functions, or the tangent lines of /geometry alone); returns the pulley
    labels (annotations, each outside its pulley opposite its hub-load arrow) for `style.separate`."""
    from matplotlib.patches import Circle

    centre = pulley_centres(res)
    radius = res.var("geometry", "pulley_radius")
    side = [str(s) for s in res.var("geometry", "side")]
    names = pulley_names(res)
    pcfg = list(res.config.get("pulleys", []))
    drv = driver_index(res)
    hub = res.var("static", "hub_load") if labels and res.has("static") else np.zeros_like(centre)
    texts = []
    first_arm = True
    for j, (c, r) in enumerate(zip(centre, radius)):
        p = pcfg[j] if j < len(pcfg) else {}
        face = OKABE_ITO[0] if j == drv else ("0.85" if side[j] == "inside" else OKABE_ITO[6])
        ax.add_patch(Circle(c, r, facecolor=face, edgecolor=color, lw=1.0, alpha=0.5, zorder=2))
        ax.plot([c[0]], [c[1]], "+", color=color, ms=5, zorder=3)
        if p.get("support") == "arm" and p.get("arm_pivot") is not None:
            pv = np.asarray(p["arm_pivot"], dtype=float)
            ax.plot([pv[0], c[0]], [pv[1], c[1]], "-", color=ARM, lw=2.5, marker="o", markevery=[0], ms=5, zorder=3,
                    label="tensioner arm and pivot" if first_arm else "_tensioner arm and pivot")
            first_arm = False
        if labels:
            what = " (driver)" if j == drv else (" (backside)" if side[j] != "inside" else "")
            what += " (arm)" if p.get("support") == "arm" else ""
            h = hub[j]
            away = -h / np.hypot(*h) if np.hypot(*h) > 0 else np.array([0.0, 1.0])  # opposite the arrow
            texts.append(ax.annotate(f"{names[j]}{what}\nR = {r * 1e3:.4g} mm", c + (r * 1.15) * away,
                                     textcoords="offset points", xytext=(0, 0), ha="left" if away[0] > 0.3 else
                                     ("right" if away[0] < -0.3 else "center"),
                                     va="bottom" if away[1] > 0.3 else ("top" if away[1] < -0.3 else "center"),
                                     fontsize=7, zorder=7, gid=f"pulley label {names[j]}",
                                     bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8}))
    a, b = tangent_points(res)
    wrap = res.var("static", "wrap_angle") if res.has("static") else res.var("geometry", "wrap_angle")
    for j, arc in enumerate(wrap_arcs(centre, radius, a, b, wrap)):
        ax.plot(arc[:, 0], arc[:, 1], "-", color=WRAP, lw=3.0, alpha=0.9, zorder=3, solid_capstyle="butt",
                label="wrap (belt on pulley)" if j == 0 else "_wrap (belt on pulley)", gid=f"wrap {names[j]}")
    if res.has("static") and res.holds("static", "node_position"):
        curves = belt_curves(res)
        spans = range(len(a))
        drawn = {s: curves.get(s, np.vstack([a[s], b[s]])) for s in spans}  # a spring span: its chord
    else:
        drawn = {s: np.vstack([a[s], b[s]]) for s in range(len(a))}
    for s, xy in drawn.items():
        ax.plot(xy[:, 0], xy[:, 1], "-", color=BELT, lw=1.2, zorder=4, gid=f"belt span {s}",
                label=belt_label if s == 0 else f"_{belt_label}")
    return texts


def plot_layout(res: Results):
    """The drive: pulleys, wraps, spans, tangent points, and the hub loads of /static as arrows to
    scale (the scale in the legend); the canvas sized to the drive's aspect, the legend below it."""
    plt = pyplot()
    centre, radius = pulley_centres(res), res.var("geometry", "pulley_radius")
    lo, hi = (centre - radius[:, None]).min(axis=0), (centre + radius[:, None]).max(axis=0)
    aspect = float(np.clip((hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-12), 0.12, 1.6))  # a thin drive: a low canvas
    fig, ax = plt.subplots(figsize=(7.0, 7.0 * 0.85 * aspect + 2.0), layout="constrained")
    labels = draw_drive(ax, res)
    a, b = tangent_points(res)
    ax.plot(np.r_[a[:, 0], b[:, 0]], np.r_[a[:, 1], b[:, 1]], "o", color=OKABE_ITO[5], ms=3.5, zorder=5,
            label="tangent points", gid="tangent points", linestyle="None")
    title = "drive layout"
    if res.has("static"):
        hub = res.var("static", "hub_load")
        size = float(np.ptp(np.r_[a, b], axis=0).max())
        top = float(np.hypot(*hub.T).max(initial=0.0))
        scale = 0.25 * size / top if top > 0 else 0.0  # the largest arrow a quarter of the drive
        ax.quiver(centre[:, 0], centre[:, 1], hub[:, 0], hub[:, 1], angles="xy", scale_units="xy",
                  scale=1.0 / scale if scale else 1.0, color=ARROW, width=0.006, zorder=6,
                  label=f"hub load, force of the belt (arrow: {top:.4g} N = {top * scale * 1e3:.3g} mm)",
                  gid="hub load")
        title += f": mean span tension {float(res.var('static', 'mean_tension')):.4g} N"
    ax.margins(0.16)  # room for the pulley labels outside the pulleys
    ax.set_aspect("equal", adjustable="datalim")  # the panel fills the canvas; the limits give way
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title)
    fig.legend(loc="outside lower center", fontsize=7, ncol=3)
    separate(fig, labels)
    return fig
