"""Mode shapes on the drive at its equilibrium (the paper's Fig. 4)."""

from __future__ import annotations

import numpy as np

from beltdyn.errors import OutputError
from beltdyn.plot.data import Results
from beltdyn.plot.drive import belt_curves, draw_drive, hermite_curves
from beltdyn.plot.style import OKABE_ITO, pyplot

DRAWN_SIZE = 0.08  # the largest drawn belt motion, a share of the drive's size
MODE = OKABE_ITO[1]
ENVELOPE = OKABE_ITO[5]


def span_normals(res: Results) -> np.ndarray:
    """(n_span, 2) unit normal of each span's chord at equilibrium (first to last node)."""
    nodes, span = res.var("static", "node_position"), res.var("static", "node_span")
    n_span = len(res.coord("static", "span"))
    out = np.zeros((n_span, 2))
    for s in np.unique(span):
        c = nodes[span == s][-1] - nodes[span == s][0]
        out[s] = np.array([-c[1], c[0]]) / max(np.hypot(*c), 1e-300)
    return out


def transverse(curves: dict[int, np.ndarray], normals: np.ndarray) -> dict[int, np.ndarray]:
    """Each span's motion projected on its chord's normal: (m, 2) vectors (w . n) n."""
    return {s: (w @ normals[s])[:, None] * normals[s][None, :] for s, w in curves.items()}


def mode_motion(res: Results, m: int, *, imag: bool = False) -> dict[int, np.ndarray]:
    """span -> (m_pts, 2) the belt's motion in mode m (0-based) through the elements' shape functions
    (node_shape with node_shape_slope; the imaginary parts with imag=True)."""
    g = res.groups["modal"]["variables"]
    sfx = "_imag" if imag else ""
    d = np.asarray(g["node_shape" + sfx])[m]
    slope_name = "node_shape_slope" + sfx
    ds = np.asarray(g[slope_name])[m] if slope_name in g else None
    length = res.var("static", "span_element_length") if res.holds("static", "span_element_length") else None
    return hermite_curves(d, ds, res.var("static", "node_span"), length)


def drawn_motion(motion: dict[int, np.ndarray], normals: np.ndarray) -> tuple[dict[int, np.ndarray], str]:
    """What a panel draws of a mode's belt motion, and in words: the transverse part (normal to each
    span's chord) when it is at least a tenth of the whole; otherwise (a longitudinal or rotational
    mode) the whole motion. The longitudinal part is left out of a transverse mode's picture: its
    uneven shift of the points along the span would make equal lobes look unequal."""
    tr = transverse(motion, normals)
    top_t = max((float(np.hypot(*w.T).max(initial=0.0)) for w in tr.values()), default=0.0)
    top = max((float(np.hypot(*w.T).max(initial=0.0)) for w in motion.values()), default=0.0)
    if top_t >= 0.1 * top and top_t > 0:
        return tr, "transverse motion"
    return motion, "motion"


def plot_modes(res: Results, modes: tuple[int, ...] | None = None):
    """A grid of mode shapes on the drive at equilibrium through the elements' shape functions, each
    scaled so that its largest drawn motion is 8 % of the drive's size (the scale in the panel),
    titled with its frequency and label; a complex mode (a running belt, node_shape_imag) drawn at
    phase 0 over its envelope (the motion at 12 phases of a cycle)."""
    plt = pyplot()
    if not res.holds("modal", "node_shape"):
        raise OutputError(f"{res.path}: /modal has no node_shape (written by beltdyn 0.1 after this feature): "
                          f"run beltdyn modal CONFIG -o {res.path} again")
    freq = res.var("modal", "frequency")
    label = [str(x) for x in res.var("modal", "label")]
    complex_modes = res.holds("modal", "node_shape_imag")
    nodes = res.var("static", "node_position")
    wanted = [m for m in (modes or range(1, min(len(freq), 8) + 1)) if 1 <= m <= len(freq)]
    if not wanted:
        raise OutputError(f"{res.path}: no mode in --modes; the file holds modes 1-{len(freq)}")
    centre, radius = res.var("static", "pulley_center"), res.var("geometry", "pulley_radius")
    lo, hi = (centre - radius[:, None]).min(axis=0), (centre + radius[:, None]).max(axis=0)
    extent = hi - lo
    aspect = float(np.clip(extent[1] / max(extent[0], 1e-12), 0.25, 1.5))
    cols = min(4 if aspect < 0.8 else 3, len(wanted))
    rows = int(np.ceil(len(wanted) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(2.9 * cols, (2.9 * aspect + 0.75) * rows + 0.3),
                             layout="constrained", squeeze=False, sharex=True, sharey=True)
    size = float(np.ptp(nodes, axis=0).max())
    normals = span_normals(res)
    base = belt_curves(res)
    for k, ax in enumerate(axes.ravel()):
        if k >= len(wanted):
            ax.set_visible(False)
            continue
        m = wanted[k] - 1
        draw_drive(ax, res, labels=False, color="0.6", belt_label="belt at equilibrium")
        w, what = drawn_motion(mode_motion(res, m), normals)
        if complex_modes:
            wi, _ = drawn_motion(mode_motion(res, m, imag=True), normals) if what == "transverse motion" else \
                (mode_motion(res, m, imag=True), what)
            z = {s: w[s] + 1j * wi[s] for s in w}
            top = max((float(np.sqrt((np.abs(v) ** 2).sum(axis=1)).max(initial=0.0)) for v in z.values()), default=0.0)
        else:
            top = max((float(np.hypot(*v.T).max(initial=0.0)) for v in w.values()), default=0.0)
        sc = DRAWN_SIZE * size / top if top > 0 else 0.0
        if complex_modes:
            for i, ph in enumerate(np.exp(1j * np.linspace(0.0, 2 * np.pi, 12, endpoint=False))[1:]):
                for s in z:
                    xy = base[s] + sc * np.real(z[s] * ph)
                    ax.plot(xy[:, 0], xy[:, 1], "-", color=ENVELOPE, lw=0.6, alpha=0.7, zorder=4,
                            label="envelope (12 phases)" if (i, s) == (0, min(z)) else "_envelope")
        for s in w:
            xy = base[s] + sc * w[s]
            ax.plot(xy[:, 0], xy[:, 1], "-", color=MODE, lw=1.6, zorder=5, gid=f"mode {m + 1} span {s}",
                    label=f"mode {m + 1}" if s == min(w) else f"_mode {m + 1}")
        ax.set_aspect("equal")
        ax.set_title(f"mode {m + 1}: {freq[m]:.4g} Hz\n{label[m]}\n{what} x {sc:.3g} "
                     f"(largest {DRAWN_SIZE * size * 1e3:.3g} mm)", fontsize=7)
    for ax in axes[-1, :]:
        ax.set_xlabel("x (m)")
    for ax in axes[:, 0]:
        ax.set_ylabel("y (m)")
    return fig

