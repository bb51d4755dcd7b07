"""`beltdyn plot`: the figures engineers look at, drawn from a results file (HDF5) alone.

Figures (each a function returning a matplotlib Figure; `figure(kind, data)` dispatches):
- layout: pulleys (names, radii, driver, backside idlers, tensioner arm and pivot), spans, tangent
  points, hub-load arrows from /static to scale;
- modes: mode shapes drawn on the drive at its static equilibrium (/static node_position plus a scaled
  /modal node_shape), labelled with frequency and kind (the paper's Fig. 4);
- sweep: tracked frequencies against the swept parameter, one line per tracked mode (the paper's
  Fig. 3b); a Campbell diagram (engine-order lines and their crossings) when the key is a speed;
- transient: histories (span tensions, hub loads, pulley speeds, arm angle, slip margin) and the
  amplitude spectra with the listed peaks annotated;
- response: amplitude against the driver speed, per engine order.

matplotlib is imported here only (the `plot` extra), so the other commands never pay for it. The
style: SI units on every axis, the Okabe-Ito colour-blind-safe palette, the configuration's title and
the beltdyn version in a corner. Plotted data are the file's data, unchanged (the tests read them back
from the figure's artists).
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from beltdyn.errors import OutputError

KINDS = ("layout", "modes", "sweep", "transient", "response")
OKABE_ITO = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442", "#000000")
NEEDS = {  # figure -> (groups it reads, the command that writes the first)
    "layout": (("geometry",), "beltdyn geometry (or static, modal)"),
    "modes": (("static", "modal"), "beltdyn modal"),
    "sweep": (("sweep",), "beltdyn sweep"),
    "transient": (("transient",), "beltdyn transient"),
    "response": (("response",), "beltdyn response"),
}


@dataclass(frozen=True, kw_only=True)
class Results:
    """What a results file holds, read once: groups by name (`results_io.read_group` dicts), the
    configuration (parsed provenance TOML, a dict) and the root attributes."""

    path: Path
    groups: dict
    config: dict
    attrs: dict

    def has(self, name: str) -> bool:
        return name in self.groups and self.groups[name]["attrs"].get("status", "complete") == "complete"

    def var(self, group: str, name: str) -> np.ndarray:
        return np.asarray(self.groups[group]["variables"][name])

    def coord(self, group: str, name: str):
        return self.groups[group]["coords"][name]


def read_results(path: Path) -> Results:
    """Every group of a beltdyn results file (OutputError, exit 2, for a missing, unreadable or foreign
    file)."""
    import h5py

    from beltdyn.results.io import read_group, read_root_attrs

    path = Path(path)
    if not path.exists():
        raise OutputError(f"{path}: no such results file (make one with beltdyn geometry/static/modal/transient/"
                          f"sweep/response CONFIG -o {path.name})")
    attrs = read_root_attrs(path)
    groups = {}
    try:
        with h5py.File(path, "r") as f:
            names = [k for k, v in f.items() if isinstance(v, h5py.Group) and k != "provenance"]
            toml = f["provenance/config_toml"][()] if "provenance/config_toml" in f else b""
            subs = [f"transient/{k}" for k in ("spectrum", "peaks") if f"transient/{k}" in f]
    except OSError as exc:
        raise OutputError(f"{path}: not a readable HDF5 results file ({exc})") from None
    for name in names + subs:
        groups[name] = read_group(path, name)
    text = toml.decode() if isinstance(toml, bytes) else str(toml)
    try:
        config = tomllib.loads(text) if text else {}
    except tomllib.TOMLDecodeError:
        config = {}
    return Results(path=path, groups=groups, config=config, attrs=attrs)


def available(res: Results) -> tuple[str, ...]:
    """The figures the file can give, in KINDS order."""
    return tuple(k for k in KINDS if all(res.has(g) for g in NEEDS[k][0]))


def require(res: Results, kind: str) -> None:
    groups, command = NEEDS[kind]
    missing = [g for g in groups if not res.has(g)]
    if missing:
        raise OutputError(f"{res.path}: the {kind} figure needs /{' and /'.join(missing)}, which this file does "
                          f"not hold (complete){_running(res, missing)}; make it with {command} CONFIG -o "
                          f"{res.path.name}")


def _running(res: Results, names: list[str]) -> str:
    """What a missing group is doing if it is marked running: written now, or left so by a dead writer."""
    for name in names:
        writer = res.groups.get(name, {}).get("writer")
        if writer is None:
            continue
        if writer["alive"] is False:
            return (f" (/{name} is marked running, but its writer, pid {writer['pid']} on {writer['host']}, no longer "
                    "runs: the next beltdyn command writing this file recovers its samples)")
        return f" (/{name} is being written by pid {writer['pid']} on {writer['host']})"
    return ""



def figure(kind: str, res: Results, *, modes: tuple[int, ...] | None = None):
    """The figure `kind` of the results (matplotlib Figure)."""
    require(res, kind)
    fig = {"layout": plot_layout, "modes": lambda r: plot_modes(r, modes), "sweep": plot_sweep,
           "transient": plot_transient, "response": plot_response}[kind](res)
    _sign(fig, res)
    return fig


# ------------------------------------------------------------------------------------ style
def _mpl():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline") \
            and not _interactive():
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"axes.prop_cycle": plt.cycler(color=OKABE_ITO), "font.size": 9, "axes.grid": True,
                         "grid.alpha": 0.3, "figure.dpi": 110, "savefig.dpi": 150, "axes.titlesize": 9})
    return plt


_SHOW = {"on": False}


def _interactive() -> bool:
    return _SHOW["on"]


def set_interactive(on: bool) -> None:
    _SHOW["on"] = bool(on)


def _sign(fig, res: Results) -> None:
    title = res.config.get("title", "") or res.path.stem
    fig.text(0.005, 0.999, f"{title} | beltdyn {res.attrs.get('beltdyn_version', '')}", ha="left", va="top",
             fontsize=6, color="0.4")


def _names(res: Results) -> list[str]:
    return [str(x) for x in res.coord("geometry", "pulley")] if res.has("geometry") else \
        [p.get("name", f"P{i}") for i, p in enumerate(res.config.get("pulleys", []))]


def _pulley_config(res: Results) -> list[dict]:
    return list(res.config.get("pulleys", []))


# ------------------------------------------------------------------------------------ layout
def _draw_drive(ax, res: Results, *, static: bool, labels: bool = True, color: str = "0.25") -> None:
    """Pulleys (at the solved centres when /static is there) and the belt (its nodes, or the tangent lines)."""
    from matplotlib.patches import Circle

    geo = "geometry"
    centre = res.var("static", "pulley_center") if static and res.has("static") else res.var(geo, "pulley_center")
    radius = res.var(geo, "pulley_radius")
    side = [str(s) for s in res.var(geo, "side")]
    names = _names(res)
    pcfg = _pulley_config(res)
    for j, (c, r) in enumerate(zip(centre, radius)):
        p = pcfg[j] if j < len(pcfg) else {}
        driver = bool(p.get("driver")) or (j == 0 and not any(q.get("driver") for q in pcfg))
        face = OKABE_ITO[0] if driver else ("0.85" if side[j] == "inside" else "#F0E442")
        ax.add_patch(Circle(c, r, facecolor=face, edgecolor=color, lw=1.0, alpha=0.6, zorder=2))
        ax.plot([c[0]], [c[1]], "+", color=color, ms=5, zorder=3)
        if p.get("support") == "arm" and p.get("arm_pivot") is not None:
            pv = np.asarray(p["arm_pivot"], dtype=float)
            ax.plot([pv[0], c[0]], [pv[1], c[1]], "-", color=OKABE_ITO[1], lw=2.5, zorder=3)
            ax.plot([pv[0]], [pv[1]], "o", color=OKABE_ITO[1], ms=5, zorder=4)
        if labels:
            what = " (driver)" if driver else (" (backside)" if side[j] != "inside" else "")
            what += " (arm)" if p.get("support") == "arm" else ""
            ax.annotate(f"{names[j]}{what}\nR = {r * 1e3:.4g} mm", c, textcoords="offset points", xytext=(0, 0),
                        ha="center", va="center", fontsize=7, zorder=5)
    if static and res.has("static") and "node_position" in res.groups["static"]["variables"]:
        nodes, span = res.var("static", "node_position"), res.var("static", "node_span")
        for s in np.unique(span):
            seg = nodes[span == s]
            ax.plot(seg[:, 0], seg[:, 1], "-", color="0.1", lw=1.2, zorder=3, gid=f"belt span {s}")
    else:
        a, b = res.var(geo, "span_start"), res.var(geo, "span_end")
        for s in range(len(a)):
            ax.plot([a[s, 0], b[s, 0]], [a[s, 1], b[s, 1]], "-", color="0.1", lw=1.2, zorder=3, gid=f"belt span {s}")


def plot_layout(res: Results):
    """The drive: pulleys, spans, tangent points, and the hub loads of /static as arrows to scale."""
    plt = _mpl()
    fig, ax = plt.subplots(figsize=(7.0, 5.0), layout="constrained")
    _draw_drive(ax, res, static=True)
    a, b = res.var("geometry", "span_start"), res.var("geometry", "span_end")
    ax.plot(np.r_[a[:, 0], b[:, 0]], np.r_[a[:, 1], b[:, 1]], "o", color=OKABE_ITO[2], ms=3, zorder=4,
            label="tangent points", gid="tangent points")
    title = "drive layout"
    if res.has("static"):
        hub = res.var("static", "hub_load")
        centre = res.var("static", "pulley_center")
        size = float(np.ptp(np.r_[a, b], axis=0).max())
        top = float(np.hypot(*hub.T).max(initial=0.0))
        scale = 0.25 * size / top if top > 0 else 0.0  # the largest arrow a quarter of the drive
        q = ax.quiver(centre[:, 0], centre[:, 1], hub[:, 0], hub[:, 1], angles="xy", scale_units="xy",
                      scale=1.0 / scale if scale else 1.0, color=OKABE_ITO[1], width=0.006, zorder=6,
                      label="hub load (force of the belt)", gid="hub load")
        ax.quiverkey(q, 0.08, 0.02, top, f"{top:.4g} N", labelpos="E", coordinates="figure")
        title += f": mean span tension {float(res.var('static', 'mean_tension')):.4g} N"
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=7)
    return fig


# ------------------------------------------------------------------------------------ modes
def plot_modes(res: Results, modes: tuple[int, ...] | None = None):
    """A grid of mode shapes on the drive at equilibrium, each scaled so that its largest belt motion is
    8 % of the drive's size, titled with its frequency and kind; a complex mode (a running belt,
    /modal node_shape_imag) drawn at phase 0 over its envelope (the motion at 12 phases of a cycle)."""
    plt = _mpl()
    if "node_shape" not in res.groups["modal"]["variables"]:
        raise OutputError(f"{res.path}: /modal has no node_shape (written by beltdyn 0.1 after this feature): "
                          f"run beltdyn modal CONFIG -o {res.path.name} again")
    freq = res.var("modal", "frequency")
    label = [str(x) for x in res.var("modal", "label")]
    shape = res.var("modal", "node_shape")
    imag = res.var("modal", "node_shape_imag") if "node_shape_imag" in res.groups["modal"]["variables"] else None
    nodes, span = res.var("static", "node_position"), res.var("static", "node_span")
    wanted = [m for m in (modes or range(1, min(len(freq), 8) + 1)) if 1 <= m <= len(freq)]
    if not wanted:
        raise OutputError(f"{res.path}: no mode in --modes; the file holds modes 1-{len(freq)}")
    cols = min(4, len(wanted))
    rows = int(np.ceil(len(wanted) / cols))
    extent = np.ptp(nodes, axis=0)
    aspect = float(np.clip(extent[1] / max(extent[0], 1e-12), 0.25, 1.5))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, (3.2 * aspect + 0.9) * rows + 0.3),
                             layout="constrained", squeeze=False)
    size = float(extent.max())
    for k, ax in enumerate(axes.ravel()):
        if k >= len(wanted):
            ax.axis("off")
            continue
        m = wanted[k] - 1
        _draw_drive(ax, res, static=True, labels=False, color="0.6")
        d = shape[m]
        if imag is not None:  # a complex mode (running belt): its envelope, the motion at 12 phases
            phases = np.exp(1j * np.linspace(0.0, 2 * np.pi, 12, endpoint=False))
            z = d + 1j * imag[m]
            top = float(np.abs(z).max(initial=0.0))
            sc = 0.08 * size / top if top > 0 else 0.0
            for ph in phases[1:]:
                w = np.real(z * ph)
                for s in np.unique(span):
                    sel = span == s
                    ax.plot(nodes[sel, 0] + sc * w[sel, 0], nodes[sel, 1] + sc * w[sel, 1], "-",
                            color=OKABE_ITO[5], lw=0.6, alpha=0.7, zorder=4)
        else:
            top = float(np.hypot(*d.T).max(initial=0.0))
            sc = 0.08 * size / top if top > 0 else 0.0
        for s in np.unique(span):
            sel = span == s
            ax.plot(nodes[sel, 0] + sc * d[sel, 0], nodes[sel, 1] + sc * d[sel, 1], "-", color=OKABE_ITO[1], lw=1.6,
                    zorder=5, gid=f"mode {m + 1} span {s}")
        ax.set_aspect("equal")
        ax.set_title(f"mode {m + 1}: {freq[m]:.4g} Hz\n{label[m]}", fontsize=8)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    return fig


# ------------------------------------------------------------------------------------ sweep
def _param(res: Results) -> tuple[str, np.ndarray, str]:
    g = res.groups["sweep"]
    keys = [k for k in g["variables"] if k.startswith("param_")]
    if not keys:
        raise OutputError(f"{res.path}: /sweep has no swept parameter")
    key = keys[0]
    name = key[len("param_"):]
    try:  # the dotted key as given (tension.target), from the sweep's own record of its parameters
        name = json.loads(g["attrs"].get("params", "[]"))[0]["key"]
    except (ValueError, KeyError, IndexError, TypeError):
        pass
    return name, np.asarray(g["variables"][key], dtype=float), key


def plot_sweep(res: Results):
    """Tracked frequencies against the (first) swept parameter; a Campbell diagram for a speed."""
    plt = _mpl()
    g = res.groups["sweep"]
    if "frequency" not in g["variables"]:
        raise OutputError(f"{res.path}: /sweep holds no frequencies (a static or transient sweep): run "
                          f"beltdyn sweep CONFIG --analysis modal")
    key, x, dataset = _param(res)
    units = g["units"].get(dataset, "")
    f = np.asarray(g["variables"]["frequency"], dtype=float)
    labels = [str(s) for s in g["variables"].get("label", [f"mode {i + 1}" for i in range(f.shape[1])])]
    order = np.argsort(x, kind="stable")
    fig, ax = plt.subplots(figsize=(7.0, 5.2), layout="constrained")
    styles = ("-", "--", ":", "-.")  # the 8 colours, then the next line style: every mode told apart
    for k in range(f.shape[1]):
        ax.plot(x[order], f[order, k], styles[(k // len(OKABE_ITO)) % 4], marker="o", ms=2.5, lw=1.2,
                color=OKABE_ITO[k % len(OKABE_ITO)], label=labels[k], gid=f"mode {k + 1}")
    campbell = "speed" in key
    if campbell:
        orders = _orders(res)
        xs = np.array([x.min(), x.max()])
        to_hz = (1.0 / (2 * np.pi)) if "rad" in units or "driver_speed" in key else 1.0
        for k in orders:
            ax.plot(xs, k * xs * to_hz, "--", color="0.35", lw=0.9, gid=f"order {k:g}")
            ax.annotate(f"order {k:g}", (xs[1], k * xs[1] * to_hz), fontsize=7, color="0.35", ha="right",
                        va="bottom")
        cx, cf = _crossings(x[order], f[order], orders, to_hz)
        if len(cx):
            ax.plot(cx, cf, "kx", ms=6, gid="crossings", label="resonances (order crossings)")
        ax.set_ylim(0.0, float(np.nanmax(f)) * 1.05)
    ax.set_xlabel(f"{key} ({units})" if units and units != "unknown" else key)
    ax.set_ylabel("frequency (Hz)")
    ax.set_title("Campbell diagram" if campbell else f"tracked natural frequencies against {key}")
    fig.legend(fontsize=6, ncol=3, loc="outside lower center")
    return fig


def _orders(res: Results) -> tuple[float, ...]:
    g = res.groups["sweep"]
    for src in (g["attrs"].get("orders"), res.config.get("running", {}).get("orders")):
        if src is None:
            continue
        if isinstance(src, str):
            try:
                src = json.loads(src)
            except ValueError:
                continue
        return tuple(float(v) for v in np.atleast_1d(src))
    return (1.0, 2.0)


def _crossings(x: np.ndarray, f: np.ndarray, orders, to_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Where a tracked frequency meets an engine-order line k x (linear interpolation between cases)."""
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


# ------------------------------------------------------------------------------------ transient
HISTORIES = (("span_tension", "span tension (N)"), ("hub_load", "hub load magnitude (N)"),
             ("pulley_speed", "pulley speed (rad/s)"), ("arm_angle", "arm angle (rad)"),
             ("slip_margin", "slip margin (1)"))


def plot_transient(res: Results):
    """Histories of the recorded series (one panel each) and their amplitude spectra with the peaks."""
    plt = _mpl()
    g = res.groups["transient"]
    t = np.asarray(g["coords"]["time"], dtype=float)
    shown = [(n, lab) for n, lab in HISTORIES if n in g["variables"]]
    spec = res.groups.get("transient/spectrum")
    rows = len(shown) + (1 if spec is not None else 0)
    fig, axes = plt.subplots(rows, 1, figsize=(7.5, 1.9 * rows + 0.4), layout="constrained", squeeze=False)
    axes = axes[:, 0]
    for ax, (name, lab) in zip(axes, shown):
        y = np.asarray(g["variables"][name], dtype=float)
        dims = g["dims"][name][1:]
        if name == "hub_load":
            y = np.hypot(y[..., 0], y[..., 1])
            dims = dims[:1]
        y2 = y.reshape(len(t), -1)
        names = _channel_names(g, dims)
        for c in range(y2.shape[1]):
            ax.plot(t, y2[:, c], lw=0.8, label=names[c], gid=f"{name} {names[c]}")
        ax.set_ylabel(lab)
        ax.legend(fontsize=6, ncol=4, loc="upper right")
    if shown:
        axes[len(shown) - 1].set_xlabel("time (s)")
    if spec is not None:
        ax = axes[-1]
        fr = np.asarray(spec["coords"]["frequency"], dtype=float)
        series = [k for k in ("span_tension", "hub_load", "midspan_displacement") if k in spec["variables"]]
        name = series[0] if series else next(iter(spec["variables"]))
        a = np.asarray(spec["variables"][name], dtype=float).reshape(len(fr), -1)
        names = _channel_names(spec, spec["dims"][name][1:])
        for c in range(a.shape[1]):
            ax.plot(fr, a[:, c], lw=0.8, label=names[c], gid=f"spectrum {name} {names[c]}")
        ax.set_yscale("log")
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel(f"{name} amplitude ({spec['units'].get(name, '')})")
        peaks = res.groups.get("transient/peaks")
        if peaks is not None:
            pv = peaks["variables"]
            sel = [i for i, s in enumerate(pv.get("series", [])) if str(s) == name]
            for i in sel[:8]:
                ax.annotate(f"{float(pv['frequency'][i]):.4g} Hz", (float(pv["frequency"][i]), float(pv["amplitude"][i])),
                            textcoords="offset points", xytext=(2, 4), fontsize=6, rotation=45)
        ax.legend(fontsize=6, ncol=4, loc="upper right")
    fig.suptitle("transient response", fontsize=10)
    return fig


def _channel_names(g: dict, dims) -> list[str]:
    import itertools

    axes = [[str(v) for v in g["coords"].get(d, [])] or [d] for d in dims]
    return [" ".join(c) for c in itertools.product(*axes)] if axes else [""]


# ------------------------------------------------------------------------------------ response
def plot_response(res: Results):
    """Amplitudes against the driver speed, one line per engine order: the largest span tension, the
    largest hub load and the arm angle (if any)."""
    plt = _mpl()
    g = res.groups["response"]
    v = g["variables"]
    speed = np.asarray(g["coords"]["speed"], dtype=float)
    orders = np.asarray(g["coords"]["order"], dtype=float)
    panels = [("span_tension_amplitude", "largest span tension amplitude (N)"),
              ("hub_load_amplitude", "largest hub load amplitude (N)")]
    if "arm_angle_amplitude" in v:
        panels.append(("arm_angle_amplitude", "arm angle amplitude (rad)"))
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.0, 2.3 * len(panels) + 0.4), layout="constrained",
                             squeeze=False, sharex=True)
    for ax, (name, lab) in zip(axes[:, 0], panels):
        a = np.asarray(v[name], dtype=float)
        if name == "hub_load_amplitude":
            a = np.hypot(a[..., 0], a[..., 1])  # the larger ellipse axis is at most this
        a = a.reshape(len(speed), len(orders), -1).max(axis=2)
        for o, k in enumerate(orders):
            ax.plot(speed, a[:, o], lw=1.2, label=f"order {k:g}", gid=f"{name} order {k:g}")
        ax.set_ylabel(lab)
        ax.set_yscale("log")
        ax.legend(fontsize=7)
    axes[-1, 0].set_xlabel("driver speed (rad/s)")
    fig.suptitle("steady forced response", fontsize=10)
    return fig


def parse_modes(text: str | None) -> tuple[int, ...] | None:
    """"1-8" / "1,3,5" / "2-4,7" -> mode numbers (1-based); None for all (up to 8)."""
    if not text:
        return None
    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-", 1)
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return tuple(out)
