"""The report's sections, each from the groups the results file holds (an empty string when it holds
none of them): drive, warnings, layout, pulleys, spans, tensioner, modes, sweep, response, transient.

Units shown: lengths in mm (radii, span lengths), angles in degrees, forces in N, torques in N m,
frequencies in Hz; each header names its unit. A table cell's `data-value` is the shown number."""

from __future__ import annotations

from html import escape

import numpy as np

from beltdyn.plot import figure
from beltdyn.plot.data import (
    Results,
    channel_names,
    meaningful_margin,
    swept_parameter,
    warnings_of,
)
from beltdyn.plot.sweep import is_campbell, sweep_range
from beltdyn.report.html import num, section, svg, table, text

RAD = 180.0 / np.pi
NO_MARGIN = "not limited (no torque)"


def _close(fig) -> None:
    import matplotlib.pyplot as plt

    plt.close(fig)


def _figure(res: Results, kind: str, figure_id: str, caption: str, **kw) -> str:
    fig = figure(kind, res, **kw)
    try:
        return svg(fig, figure_id, caption)
    finally:
        _close(fig)


def drive(res: Results) -> str:
    """Title, configuration hash, version, dates, and the resolved TOML folded away."""
    a = res.attrs
    rows = [("results file", str(res.path)), ("configuration SHA-256", str(a.get("config_sha256", "n/a"))),
            ("beltdyn version", str(a.get("beltdyn_version", "n/a"))), ("written (UTC)", str(a.get("modified_utc", a.get("created_utc", "n/a")))),
            ("groups", ", ".join("/" + g for g in res.groups))]
    meta = "".join(f"<tr><th>{escape(k)}</th><td>{escape(v)}</td></tr>" for k, v in rows)
    toml = (f"<details><summary>resolved configuration (TOML)</summary><pre>{escape(res.config_text)}</pre></details>"
            if res.config_text else "")
    return f'<header id="drive"><h1>{escape(res.title)}</h1><table class="meta" id="meta">{meta}</table>{toml}</header>'


def warnings(res: Results) -> str:
    """Every group's warnings, in words, and the slip margins below 1 (the belt slips)."""
    items = [f"/{g}: {w}" for g, w in warnings_of(res)]
    if res.holds("static", "slip_margin"):
        names = [str(p) for p in res.coord("static", "pulley")]
        for n, m in zip(names, res.var("static", "slip_margin")):
            if np.isfinite(m) and m < 1.0:
                items.append(f"/static: pulley {n} slips (slip margin {m:.3g} < 1)")
    if res.has("transient") and float(res.groups["transient"]["attrs"].get("worst_slip_margin", np.inf)) < 1.0:
        at = res.groups["transient"]["attrs"]
        items.append(f"/transient: pulley {at.get('worst_slip_pulley')} slips at t = {float(at['worst_slip_time_s']):.4g} s "
                     f"(slip margin {float(at['worst_slip_margin']):.3g} < 1)")
    if not items:
        return ('<section id="warnings"><h2>Warnings</h2><p>None: no group of this file holds a warning.</p>'
                "</section>")
    lis = "".join(f"<li>{escape(w)}</li>" for w in items)
    return f'<section id="warnings" class="warnings"><h2>Warnings</h2><ul>{lis}</ul></section>'


def _pulley_names(res: Results) -> list[str]:
    return [str(p) for p in res.coord("geometry", "pulley")]


def _roles(res: Results) -> list[tuple[str, str]]:
    """(role, support) of each pulley from the configuration and /geometry's sides."""
    pcfg = list(res.config.get("pulleys", []))
    side = [str(s) for s in res.var("geometry", "side")]
    drv = next((j for j, p in enumerate(pcfg) if p.get("driver")), 0)
    out = []
    for j, s in enumerate(side):
        p = pcfg[j] if j < len(pcfg) else {}
        role = "driver" if j == drv else ("backside idler" if s != "inside" and not p.get("arm_pivot") else
                                          ("tensioner" if p.get("support") == "arm" else "driven"))
        if role == "driven" and s != "inside":
            role = "backside"
        out.append((role, str(p.get("support", "fixed"))))
    return out


def layout(res: Results) -> str:
    if not res.has("geometry"):
        return ""
    return section("layout", "Layout", _figure(res, "layout", "figure-layout",
                                               "The drive at its equilibrium: pulleys with their wraps (green), "
                                               "tangent points, belt spans, tensioner arms, hub-load arrows to "
                                               "scale (the force of the belt on each pulley)."))


def pulleys(res: Results) -> str:
    """Name, role, support, radius, wrap, hub load (magnitude, direction), applied torque, required
    friction, slip margin; the slip arc and speed ratio where the file holds them."""
    if not res.has("geometry"):
        return ""
    names = _pulley_names(res)
    st = res.has("static")
    g = "static" if st else "geometry"
    radius, wrap = res.var("geometry", "pulley_radius"), res.var(g, "wrap_angle")
    headers = ["pulley", "role", "support", "radius (mm)", "wrap (deg)"]
    extra = [(n, h) for n, h in (("slip_arc", "slip arc (deg)"), ("speed_ratio", "speed ratio (1)")) if res.holds("static", n)]
    if st:
        headers += ["hub load (N)", "hub load direction (deg)", "applied torque (N m)", "required friction (1)",
                    "slip margin (1)"] + [h for _, h in extra]
    rows = []
    left_out = []
    for j, n in enumerate(names):
        role, support = _roles(res)[j]
        row = [text(n), text(role), text(support), num(radius[j] * 1e3), num(wrap[j] * RAD)]
        if st:
            h = res.var("static", "hub_load")[j]
            row += [num(res.var("static", "hub_load_magnitude")[j]), num(np.degrees(np.arctan2(h[1], h[0])))]
            row += [num(res.var("static", "applied_torque")[j]) if res.holds("static", "applied_torque") else text("n/a")]
            row += [num(res.var("static", "required_friction")[j]) if res.holds("static", "required_friction") else text("n/a")]
            if res.holds("static", "slip_margin"):
                m = float(res.var("static", "slip_margin")[j])
                if meaningful_margin(m) or np.isnan(m):
                    row.append(num(m))
                else:
                    row.append(text(NO_MARGIN))
                    left_out.append(n)
            else:
                row.append(text("n/a"))
            for var, _ in extra:
                v = res.var("static", var)[j]
                row.append(num(v * RAD if var == "slip_arc" else v))
        rows.append(row)
    note = ("Hub load direction: of the force of the belt on the pulley, counter-clockwise from +x. "
            + (f"Slip margin of {', '.join(left_out)}: no torque, so friction is not needed (a margin of "
               "10^12 or more, or infinite, in the file)." if left_out else ""))
    return section("pulleys", "Pulleys", table("table-pulleys", "Pulleys" + (" at the static equilibrium" if st else
                                                                         " (geometry)"), headers, rows, note))


def spans(res: Results) -> str:
    """Length, tensions at both ends, model, elements, first transverse frequency of each span."""
    if not res.has("geometry"):
        return ""
    st = res.has("static")
    g = "static" if st else "geometry"
    names = [str(s) for s in res.coord(g, "span")]
    length = res.var(g, "span_length")
    headers = ["span", "length (mm)"]
    if st:
        headers += ["tension at start (N)", "tension at end (N)", "model", "elements"]
    first = _first_transverse(res, len(names))
    if first is not None:
        headers.append("1st transverse (Hz)")
    rows = []
    for s, n in enumerate(names):
        row = [text(n), num(length[s] * 1e3)]
        if st:
            T = res.var("static", "span_tension")[s]
            row += [num(T[0]), num(T[1])]
            row += [text(res.var("static", "span_model")[s]) if res.holds("static", "span_model") else text("ancf")]
            row += [num(res.var("static", "span_elements")[s]) if res.holds("static", "span_elements") else text("n/a")]
        if first is not None:
            row.append(num(first[s]))
        rows.append(row)
    return section("spans", "Belt spans", table("table-spans", "Belt spans", headers, rows))


def _first_transverse(res: Results, n_span: int) -> np.ndarray | None:
    """(n_span,) the lowest frequency of a mode labelled transverse of each span (NaN if none)."""
    if not res.has("modal"):
        return None
    kind = [str(k) for k in res.var("modal", "kind")]
    span = res.var("modal", "span")
    f = res.var("modal", "frequency")
    out = np.full(n_span, np.nan)
    for m in np.argsort(f, kind="stable"):
        s = int(span[m]) - 1
        if kind[m] == "transverse" and 0 <= s < n_span and np.isnan(out[s]):
            out[s] = f[m]
    return out


def tensioner(res: Results) -> str:
    """Arm angle, free angle, spring torque, pivot reaction, stops of each tensioner arm."""
    if not res.holds("static", "arm_angle"):
        return ""
    angle = res.var("static", "arm_angle")
    arms = [j for j in range(len(angle)) if np.isfinite(angle[j])]
    if not arms:
        return ""
    names = [str(p) for p in res.coord("static", "pulley")]
    pcfg = list(res.config.get("pulleys", []))
    rows = []
    for j in arms:
        R = res.var("static", "pivot_reaction")[j]
        stops = pcfg[j].get("arm_range") if j < len(pcfg) else None
        rows.append([text(names[j]), num(angle[j] * RAD), num(res.var("static", "arm_free_angle")[j] * RAD),
                     num(res.var("static", "arm_torque")[j]), num(np.hypot(*R)), num(np.degrees(np.arctan2(R[1], R[0]))),
                     text("none" if not stops else f"{stops[0] * RAD:.4g} to {stops[1] * RAD:.4g} deg")])
    headers = ["pulley", "arm angle (deg)", "free angle (deg)", "spring torque (N m)", "pivot reaction (N)",
               "pivot reaction direction (deg)", "stops"]
    return section("tensioner", "Tensioner", table("table-tensioner", "Tensioner arms at the static equilibrium",
                                                   headers, rows, "Angles counter-clockwise from +x."))


def modes(res: Results, shown: int = 8) -> str:
    """The modes table (frequency, label, energy shares) and the first shapes drawn."""
    if not res.has("modal"):
        return ""
    f = res.var("modal", "frequency")
    label = [str(x) for x in res.var("modal", "label")]
    kinds = [str(k) for k in res.coord("modal", "energy_kind")]
    share = res.var("modal", "energy_share")
    rows = [[num(m + 1), num(f[m]), text(label[m]), *[num(share[m, k]) for k in range(len(kinds))]]
            for m in range(len(f))]
    parts = [table("table-modes", "Natural frequencies and kinetic-energy shares", ["mode", "frequency (Hz)", "label"]
                   + [f"{k} share (1)" for k in kinds], rows)]
    if res.has("static") and res.holds("modal", "node_shape"):
        parts.append(_figure(res, "modes", "figure-modes", f"The first {min(shown, len(f))} mode shapes on the drive "
                             "at equilibrium, through the elements' shape functions; the drawing scale in each "
                             "panel.", modes=tuple(range(1, min(shown, len(f)) + 1))))
    return section("modes", "Modes", *parts)


def sweep(res: Results) -> str:
    """The swept figure and its table: the crossings of a Campbell diagram, the tracked frequencies, or
    a static sweep's quantities (a torque sweep: the tensioner's working curve)."""
    if not res.has("sweep"):
        return ""
    key, x, units = swept_parameter(res)
    parts = [f"<p>Swept: {escape(sweep_range(res))}.</p>",
             _figure(res, "sweep", "figure-sweep", f"Against {key}.")]
    g = res.groups["sweep"]
    unit = f" ({units})" if units else ""
    if is_campbell(res) and res.holds("sweep", "crossing_frequency"):
        cf = res.var("sweep", "crossing_frequency")
        cx = res.var("sweep", "crossing_driver_speed") if res.holds("sweep", "crossing_driver_speed") else \
            np.full(len(cf), np.nan)
        order = res.var("sweep", "crossing_order")
        lab = [str(s) for s in res.var("sweep", "crossing_label")]
        rows = [[num(order[i]), text(lab[i]), num(cx[i]), num(cf[i])] for i in np.argsort(cx, kind="stable")]
        parts.append(table("table-crossings", "Engine-order crossings (resonances)",
                           ["order", "mode", "driver speed (rad/s)", "frequency (Hz)"], rows))
    elif res.holds("sweep", "frequency"):
        f = res.var("sweep", "frequency")
        labels = [str(s) for s in res.var("sweep", "label")] if res.holds("sweep", "label") else \
            [f"mode {k + 1}" for k in range(f.shape[1])]
        rows = [[num(x[i]), *[num(f[i, k]) for k in range(f.shape[1])]] for i in np.argsort(x, kind="stable")]
        parts.append(table("table-sweep", "Tracked natural frequencies (Hz)", [key + unit] + labels, rows))
    else:
        headers, cols = [key + unit], []
        for name, shown in (("arm_angle", "arm angle"), ("arm_torque", "spring torque"),
                            ("spring_torque", "spring torque"), ("slip_margin", "slip margin")):
            if name not in g["variables"]:
                continue
            y = np.asarray(g["variables"][name], dtype=float).reshape(len(x), -1)
            cn = channel_names(g, g["dims"][name][1:])
            for c in range(y.shape[1]):
                col = y[:, c]
                if not np.isfinite(col).any() or (name == "slip_margin" and not all(meaningful_margin(v) for v in col)):
                    continue
                headers.append(f"{shown} {cn[c]} ({g['units'].get(name, '')})")
                cols.append(col)
        rows = [[num(x[i]), *[num(c[i]) for c in cols]] for i in np.argsort(x, kind="stable")]
        parts.append(table("table-sweep", "Swept static quantities", headers, rows,
                           "Slip margins of pulleys without torque (not limited) left out."))
    return section("sweep", "Sweep", *parts)


def response(res: Results) -> str:
    """The amplitude figure and a table of the peaks per order: the largest span tension and hub load
    amplitudes, the speed and frequency where they occur."""
    if not res.has("response"):
        return ""
    from beltdyn.plot.series import response_curves

    g = res.groups["response"]
    speed = np.asarray(g["coords"]["speed"], dtype=float)
    orders = np.asarray(g["coords"]["order"], dtype=float)
    freq = res.var("response", "frequency")
    T = response_curves(g["variables"]["span_tension_amplitude"], "span_tension_amplitude", len(speed), len(orders))
    H = response_curves(g["variables"]["hub_load_amplitude"], "hub_load_amplitude", len(speed), len(orders))
    rows = []
    for o, k in enumerate(orders):
        i, j = int(np.argmax(T[:, o])), int(np.argmax(H[:, o]))
        rows.append([num(k), num(T[i, o]), num(speed[i]), num(freq[i, o]), num(H[j, o]), num(speed[j])])
    headers = ["order", "largest span tension amplitude (N)", "at driver speed (rad/s)", "excitation frequency (Hz)",
               "largest hub load amplitude (N)", "at driver speed (rad/s)"]
    return section("response", "Steady forced response",
                   _figure(res, "response", "figure-response", "Amplitudes against the driver speed per engine order."),
                   table("table-response", "Peaks of the forced response per engine order", headers, rows,
                         "Hub load amplitude: the magnitude of its two components' amplitudes."))


def transient(res: Results) -> str:
    """History panels and spectrum, the extreme values with their times, the worst slip margin, the
    energy-balance error, the spectrum's peaks."""
    if not res.has("transient"):
        return ""
    from beltdyn.plot.series import HISTORIES, history_channels, shown_channels

    g = res.groups["transient"]
    at = g["attrs"]
    t = np.asarray(g["coords"]["time"], dtype=float)
    rows = []
    for name, lab in HISTORIES:
        if name not in g["variables"]:
            continue
        y, names = history_channels(g, name, len(t))
        for c in shown_channels(name, y):
            i, j = int(np.nanargmin(y[:, c])), int(np.nanargmax(y[:, c]))
            rows.append([text(lab.split(" (")[0]), text(names[c]), text(lab.split("(")[-1].rstrip(")")),
                         num(y[i, c]), num(t[i]), num(y[j, c]), num(t[j])])
    extremes = table("table-extremes", "Extreme values and their times",
                     ["quantity", "channel", "unit", "minimum", "at time (s)", "maximum", "at time (s)"], rows,
                     "Slip margins of pulleys without torque (not limited) left out.")
    summary = [("duration (s)", at.get("duration_s")), ("time step (s)", at.get("step_s")),
               ("energy-balance error (1)", at.get("energy_balance_error")),
               ("worst slip margin (1)", at.get("worst_slip_margin")),
               ("worst slip margin at time (s)", at.get("worst_slip_time_s")),
               ("slack-span events", at.get("n_slack_events"))]
    srows = [[text(k), num(float(v))] for k, v in summary if v is not None]
    if at.get("worst_slip_pulley") is not None:
        srows.append([text("worst slip margin on pulley"), text(at.get("worst_slip_pulley"))])
    parts = [table("table-transient", "Transient run", ["quantity", "value"], srows),
             _figure(res, "transient", "figure-transient", "Histories and the amplitude spectrum with its peaks."),
             extremes]
    peaks = res.groups.get("transient/peaks")
    if peaks is not None:
        pv = peaks["variables"]
        prow = [[text(pv["series"][i]), text(pv["channel"][i]), num(pv["frequency"][i]), num(pv["amplitude"][i]),
                 text(pv["amplitude_unit"][i]), text(pv["relation"][i])] for i in range(len(pv["frequency"]))]
        parts.append(table("table-peaks", "Dominant spectral peaks", ["series", "channel", "frequency (Hz)",
                                                                      "amplitude", "unit", "relation"], prow))
    return section("transient", "Transient response", *parts)



SECTIONS = (drive, warnings, layout, pulleys, spans, tensioner, modes, sweep, response, transient)
