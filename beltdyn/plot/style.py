"""The figures' style and their checks: Okabe-Ito colours combined with markers and line styles so
that no two curves of one panel look alike, the corner tag placed by the layout engine, text labels
moved apart until none overlaps another, and the two checks the tests (and anyone) can run on a
figure: curves that look alike, and text boxes that overlap."""

from __future__ import annotations

import itertools

import matplotlib

OKABE_ITO = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442", "#000000")
LINESTYLES = ("-", "--", ":", "-.")
MARKERS = ("o", "s", "^", "v", "D", "P", "X")  # 7 markers against 8 colours: (colour, marker) repeats after 56
STYLE = {"axes.prop_cycle": matplotlib.cycler(color=OKABE_ITO), "font.size": 9, "axes.grid": True,
         "grid.alpha": 0.3, "figure.dpi": 110, "savefig.dpi": 150, "axes.titlesize": 9,
         "axes.formatter.useoffset": False}
_SHOW = {"on": False}


def curve_style(k: int) -> dict:
    """The k-th curve's look: colour k mod 8, marker k mod 7 (hollow, so that a curve drawn over its
    degenerate twin leaves the twin's markers visible), line style k // 8; markers on alternate
    samples, the odd curves' between the even ones'. Distinct for k < 224."""
    return {"color": OKABE_ITO[k % len(OKABE_ITO)], "linestyle": LINESTYLES[(k // len(OKABE_ITO)) % len(LINESTYLES)],
            "marker": MARKERS[k % len(MARKERS)], "fillstyle": "none", "markevery": (k % 2, 2), "ms": 4.0}


def set_interactive(on: bool) -> None:
    """Figures for a window (--show) rather than for files: leave the backend as it is."""
    _SHOW["on"] = bool(on)


def pyplot():
    """matplotlib.pyplot with the house style (Agg unless a window was asked for)."""
    if not _SHOW["on"] and matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update(STYLE)
    return plt


def sign(fig, tag: str) -> None:
    """The corner tag (what the figure shows, the configuration's title, the version) as the figure's
    suptitle, left-aligned: the layout engine keeps it clear of every title and label."""
    fig.suptitle(tag, x=0.01, ha="left", fontsize=7, color="0.35")


def renderer(fig):
    """The figure's renderer after the layout engine has settled: constrained layout places the
    texts from the previous draw's sizes, so it takes two draws to converge (measured: after one, a
    mode panel's three-line title still overlapped the corner tag)."""
    settle(fig)
    return fig.canvas.get_renderer()


def settle(fig) -> None:
    """Draw twice: the layout engine's positions final (see `renderer`)."""
    fig.canvas.draw()
    fig.canvas.draw()


def separate(fig, texts, *, tries: int = 16) -> None:
    """Move annotations (placed with offset points) apart: each, in turn, is shifted up or down by its
    own height (alternately, further each try) until its box overlaps no text placed before it nor any
    other visible text of the figure."""
    if not texts:
        return
    r = renderer(fig)
    movable = set(map(id, texts))
    placed = [t.get_window_extent(r) for t in visible_texts(fig) if id(t) not in movable]
    for t in texts:
        x0, y0 = t.xyann
        h = t.get_window_extent(r).height * 72.0 / fig.dpi + 1.0
        for k in range(tries):
            step = (k + 1) // 2 * (1 if k % 2 else -1)
            t.xyann = (x0, y0 + step * h)
            box = t.get_window_extent(r)
            if not any(box.overlaps(p) for p in placed):
                break
        placed.append(t.get_window_extent(r))


def visible_texts(fig) -> list:
    """Every text the figure draws: visible, non-empty, in a visible axes; of the tick labels only
    those of the ticks the axis draws (its current locations inside the view)."""
    from matplotlib.text import Text

    drawn, tick_labels = set(), set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            for locs, ticks in ((axis.get_majorticklocs(), axis.get_major_ticks()),
                                (axis.get_minorticklocs(), axis.get_minor_ticks())):
                tick_labels.update(id(lab) for tick in ticks for lab in (tick.label1, tick.label2))
                lo, hi = sorted(axis.get_view_interval())
                pad = 1e-9 * max(1.0, abs(hi - lo))
                for tick, loc in zip(ticks, locs):
                    if ax.get_visible() and ax.axison and lo - pad <= loc <= hi + pad:
                        drawn.update(id(lab) for lab in (tick.label1, tick.label2) if lab.get_visible())
    out = []
    for t in fig.findobj(Text):
        if not t.get_text().strip() or not t.get_visible():
            continue
        if t.axes is not None and not t.axes.get_visible():
            continue
        if id(t) in tick_labels and id(t) not in drawn:
            continue
        out.append(t)
    return out


def overlapping_texts(fig, *, tolerance_px: float = 0.5) -> list[tuple[str, str]]:
    """Pairs of drawn texts whose rendered boxes overlap by more than `tolerance_px` in both
    directions (a shared edge is not an overlap)."""
    r = renderer(fig)
    boxes = [(t.get_text(), t.get_window_extent(r)) for t in visible_texts(fig)]
    out = []
    for (a, ba), (b, bb) in itertools.combinations(boxes, 2):
        w = min(ba.x1, bb.x1) - max(ba.x0, bb.x0)
        h = min(ba.y1, bb.y1) - max(ba.y0, bb.y0)
        if w > tolerance_px and h > tolerance_px:
            out.append((a, b))
    return out


def look(line) -> tuple:
    """What tells a curve apart to the eye: colour, line style, marker and its fill."""
    from matplotlib.colors import to_rgba

    marker = line.get_marker()
    has_marker = marker not in (None, "None", "", " ")
    return (to_rgba(line.get_color()), line.get_linestyle() if line.get_linestyle() not in (" ", "") else "None",
            marker if has_marker else "", line.get_fillstyle() if has_marker else "")


def alike_curves(fig) -> list[tuple[str, str]]:
    """Pairs of curves of one panel, of two different items (labels, a leading '_' ignored), that look
    alike (same colour, dash pattern, marker and fill). Unlabelled lines (matplotlib's `_child` names:
    centre marks, guides) are not curves."""
    out = []
    for ax in fig.axes:
        seen: dict[tuple, str] = {}
        for line in ax.get_lines():
            label = line.get_label().lstrip("_")
            if not label or label.startswith("child") or not line.get_visible():
                continue
            key = look(line)
            other = seen.get(key)
            if other is not None and other != label:
                out.append((other, label))
            seen.setdefault(key, label)
    return out
