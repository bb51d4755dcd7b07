"""The tables the commands print: geometry, statics, modes, the paper's tables, span-model choice,
response, transient summary and peaks, sweeps and the Campbell crossings."""

from __future__ import annotations

from beltdyn.cli.console import console, plural


def degrees_180(angle: float) -> float:
    """A direction in degrees in (-180, 180]."""
    import math

    d = math.degrees(angle) % 360.0
    return d - 360.0 if d > 180.0 else d


def print_geometry(layout) -> None:
    import math

    from rich.table import Table

    con = console()
    t = Table(title="Pulleys")
    for col in ("pulley", "x (m)", "y (m)", "radius (m)", "side", "wrap (deg)", "arc (m)"):
        t.add_column(col, justify="right" if col not in ("pulley", "side") else "left")
    for j, name in enumerate(layout.names):
        t.add_row(name, f"{layout.center[j, 0]:.7f}", f"{layout.center[j, 1]:.7f}", f"{layout.radius[j]:.5g}",
                  "inside" if layout.side_sign[j] > 0 else "backside", f"{math.degrees(layout.wrap_angle[j]):.4f}",
                  f"{layout.arc_length[j]:.7f}")
    con.print(t)
    s = Table(title="Spans")
    for col in ("span", "length (m)", "angle (deg)"):
        s.add_column(col, justify="right" if col != "span" else "left")
    for i in range(layout.n):
        s.add_row(layout.span_name(i), f"{layout.span_length[i]:.7f}", f"{degrees_180(layout.span_angle[i]):.4f}")
    con.print(s)
    extra = ""
    if layout.adjust_index is not None:
        name = layout.names[layout.adjust_index]
        if layout.adjust_kind == "arm":
            extra = f"; the arm of pulley {name} turned {math.degrees(layout.adjust_offset):.4f} deg about its pivot"
        else:
            extra = f"; adjustable pulley {name} moved {layout.adjust_offset * 1e3:.4f} mm along its slide"
    con.print(f"belt length {layout.belt_length:.10f} m{extra}")


def print_static(layout, model, res) -> None:
    import math

    import numpy as np
    from rich.table import Table

    con = console()
    speed = f" of the belt running at {model.belt_speed:.4g} m/s" if model.belt_speed else ""
    t = Table(title=f"Static equilibrium{speed} ({plural(res.iterations, 'Newton iteration')}, {model.n_dof} DOFs)")
    for col in ("span", "tension start (N)", "tension end (N)"):
        t.add_column(col, justify="right" if col != "span" else "left")
    for i in range(layout.n):
        t.add_row(layout.span_name(i), f"{res.span_tension[i, 0]:.4f}", f"{res.span_tension[i, 1]:.4f}")
    con.print(t)
    h = Table(title="Pulleys")
    slip = res.slip_margin is not None and not np.all(np.isnan(res.slip_margin))
    loads = res.applied_torque is not None and np.any(res.applied_torque)
    cols = ["pulley", "x (m)", "y (m)", "hub load x (N)", "hub load y (N)", "|hub load| (N)"]
    cols += ["torque (N m)"] if loads else []
    cols += ["tight (N)", "slack (N)", "mu required", "slip margin"] if slip else []
    for col in cols:
        h.add_column(col, justify="right" if col != "pulley" else "left")
    from beltdyn.model.slip import pulley_tensions

    t_in, t_out = pulley_tensions(res.span_tension)
    for j, name in enumerate(layout.names):
        row = [name, f"{res.pulley_center[j, 0]:.7f}", f"{res.pulley_center[j, 1]:.7f}", f"{res.hub_load[j, 0]:.3f}",
               f"{res.hub_load[j, 1]:.3f}", f"{float((res.hub_load[j] ** 2).sum()) ** 0.5:.3f}"]
        if loads:
            row.append(f"{res.applied_torque[j]:.4g}" if j != model.driver else f"{res.driver_torque:.4g} (driver)")
        if slip:
            row += [f"{max(t_in[j], t_out[j]):.3f}", f"{min(t_in[j], t_out[j]):.3f}",
                    f"{res.required_friction[j]:.4g}", "-" if np.isnan(res.slip_margin[j]) else f"{res.slip_margin[j]:.3g}"]
        h.add_row(*row)
    con.print(h)
    if slip and res.wraps is not None:
        w = res.wraps
        wt = Table(title="Wraps (creep)")
        for col in ("pulley", "adhesion arc (deg)", "slip arc (deg)", "rim speed ratio", "creep loss (W)", "gross slip"):
            wt.add_column(col, justify="right" if col != "pulley" else "left")
        for j, name in enumerate(layout.names):
            wt.add_row(name, f"{math.degrees(w.adhesion_arc[j]):.2f}", f"{math.degrees(w.slip_arc[j]):.2f}",
                       f"{w.rim_speed_ratio[j]:.6f}", f"{w.creep_power_loss[j]:.4g}", "yes" if w.gross_slip[j] else "no")
        con.print(wt)
    if res.arm_angle is not None and not np.all(np.isnan(res.arm_angle)):
        a = Table(title="Tensioner arms")
        for col in ("pulley", "arm angle (deg)", "spring torque (N m)", "spring free angle (deg)",
                    "pivot reaction x (N)", "pivot reaction y (N)"):
            a.add_column(col, justify="right" if col != "pulley" else "left")
        for j, name in enumerate(layout.names):
            if np.isnan(res.arm_angle[j]):
                continue
            a.add_row(name, f"{math.degrees(res.arm_angle[j]):.4f}", f"{res.arm_torque[j]:.4f}",
                      "-" if np.isnan(res.arm_free_angle[j]) else f"{math.degrees(res.arm_free_angle[j]):.4f}",
                      f"{res.pivot_reaction[j, 0]:.3f}", f"{res.pivot_reaction[j, 1]:.3f}")
        con.print(a)
    if layout.adjust_index is not None and layout.adjust_kind == "arm":
        moved = f"the arm of pulley {layout.names[layout.adjust_index]} turned {math.degrees(res.adjust_offset):.4f} deg"
    else:
        moved = f"adjustable pulley offset {res.adjust_offset * 1e3:.4f} mm"
    con.print(f"mean span tension {res.mean_tension:.6f} N; driver torque {res.driver_torque:.4g} N m; {moved}")
    from beltdyn.results.export import static_warnings

    for w in static_warnings(model, res):
        con.print(f"[bold yellow]warning:[/] {w}")


def print_modal(mres) -> None:
    import numpy as np
    from rich.table import Table

    con = console()
    speed = f" at belt speed {mres.belt_speed:.4g} m/s (gyroscopic)" if mres.belt_speed else ""
    t = Table(title=f"Modes{speed} ({mres.solver} solver; {mres.n_rigid} rigid-body mode(s) excluded)")
    tens = bool(mres.energy_share[:, 4].any()) if mres.energy_share.shape[1] > 4 else False
    unstable = mres.growth_rate is not None and bool(np.any(mres.growth_rate > 0))
    for col in ("mode", "frequency (Hz)") + (("growth (1/s)",) if unstable else ()) + \
            ("modal shape", "rot", "trans", "long", "transv") + (("tens",) if tens else ()):
        t.add_column(col, justify="left" if col == "modal shape" else "right")
    for k in range(len(mres.frequency)):
        sh = mres.energy_share[k][: 5 if tens else 4]
        growth = (f"{mres.growth_rate[k]:.4g}",) if unstable else ()
        t.add_row(str(k + 1), f"{mres.frequency[k]:.3f}", *growth, mres.label[k], *(f"{x:.2f}" for x in sh))
    con.print(t)
    if unstable:
        con.print(f"[bold yellow]warning:[/] the running belt is unstable at {mres.belt_speed:.4g} m/s: above its first "
                  f"critical speed {mres.critical_speed:.4g} m/s (about this equilibrium) a span diverges "
                  f"(frequency 0, growth rate > 0)")


def print_paper(rows) -> None:
    from rich.table import Table

    con = console()
    t = Table(title="Paper Tables 1 and 2: theoretical (paper), experimental (paper), beltdyn")
    for col in ("case", "mode", "modal shape", "paper theory (Hz)", "paper exp. (Hz)", "beltdyn (Hz)",
                "vs theory (%)", "vs exp. (%)"):
        t.add_column(col, justify="right" if "Hz" in col or "%" in col or col == "mode" else "left")
    for r in rows:
        t.add_row(r.case, str(r.mode), r.shape, f"{r.theory:.1f}", "-" if r.experiment is None else f"{r.experiment:.1f}",
                  f"{r.ours:.3f}", f"{r.diff_theory_pct:+.3f}",
                  "-" if r.diff_experiment_pct is None else f"{r.diff_experiment_pct:+.2f}")
    con.print(t)

def print_response(con, res) -> None:
    """Per order: the largest span-tension and hub-load amplitudes over the speeds, and where."""
    import numpy as np
    from rich.table import Table

    for w in res.warnings:
        con.print(f"[bold yellow]warning[/]: {w}")
    table = Table(title=f"steady response, {len(res.speed)} speeds {res.speed[0]:.6g}-{res.speed[-1]:.6g} rad/s "
                        f"(prescribed: {', '.join(res.prescribed)})")
    for col in ("order", "largest tension amplitude", "at speed", "frequency", "largest hub-load amplitude",
                "at speed"):
        table.add_column(col, justify="right")
    T = np.abs(res.outputs["span_tension"]).max(axis=(2, 3))
    H = np.linalg.norm(np.abs(res.outputs["hub_load"]), axis=-1).max(axis=2)
    for o, k in enumerate(res.orders):
        i, j = int(np.argmax(T[:, o])), int(np.argmax(H[:, o]))
        table.add_row(f"{k:g}", f"{T[i, o]:.4g} N", f"{res.speed[i]:.5g} rad/s", f"{res.frequency[i, o]:.5g} Hz",
                      f"{H[j, o]:.4g} N", f"{res.speed[j]:.5g} rad/s")
    con.print(table)

def print_sweep(con, result, pulleys: list[str]) -> None:
    import numpy as np
    from rich.table import Table

    from beltdyn.study.sweep import richardson, static_columns

    spec = result.spec
    keys = [p.key for p in spec.params]
    n = spec.n_cases
    show = list(range(n)) if n <= 24 else sorted(set(np.linspace(0, n - 1, 24).round().astype(int)))
    tbl = Table(title=f"Sweep: {spec.analysis}, {n} cases" + (" (every case)" if n <= 24 else " (a selection)"))
    for k in keys:
        tbl.add_column(k, justify="right")
    n_show = 0
    if result.frequency is not None:
        n_show = min(6, result.frequency.shape[1])
        for j in range(n_show):
            tbl.add_column(f"{result.label[j]} (Hz)" if j < len(result.label) else f"mode {j + 1}", justify="right")
    columns = static_columns(result, pulleys) if result.frequency is None else ()
    for c in columns:
        tbl.add_column(c.title, justify="right")
    n_show = n_show or len(columns)
    tbl.add_column("wall (ms)", justify="right")
    for i in show:
        row = [f"{v:g}" if isinstance(v, (int, float)) else str(v) for v in result.values[i]]
        if result.failed[i]:
            row += ["failed"] + [""] * (n_show - 1 if n_show else 0)
        elif result.frequency is not None:
            row += [f"{result.frequency[i, j]:.3f}" for j in range(n_show)]
        else:
            row += [c.cells[i] for c in columns]
        row.append(f"{result.wall_time[i] * 1e3:.1f}")
        tbl.add_row(*row)
    con.print(tbl)
    if result.frequency is not None and keys == ["mesh.elements_per_span"] and n >= 2 and not result.failed.any():
        # distinct meshes, coarse to fine (a range may round to repeated or unordered counts)
        elements_all = np.array([v[0] for v in result.values], dtype=float)
        uniq, first_idx = np.unique(elements_all, return_index=True)
        if len(uniq) < 2:
            return
        sel = first_idx[np.argsort(uniq)]
        elements = elements_all[sel]
        f_inf, est, p = richardson(result.frequency[sel], elements)
        n = len(sel)
        conv = Table(title="Mesh convergence: Richardson-extrapolated error estimate per mode")
        conv.add_column("el/span", justify="right")
        for j in range(n_show):
            conv.add_column(result.label[j], justify="right")
        conv.add_column("wall (ms)", justify="right")
        for i in range(n):
            conv.add_row(str(int(elements[i])), *[f"{est[i, j]:.1e}" for j in range(n_show)],
                         f"{result.wall_time[sel[i]] * 1e3:.1f}")
        conv.add_row("f_inf (Hz)", *[f"{f_inf[j]:.4f}" for j in range(n_show)], "")
        conv.add_row("order p", *[f"{p[j]:.2f}" for j in range(n_show)], "")
        con.print(conv)


def print_campbell(con, cfg, result) -> None:
    """A speed sweep's resonance table: the engine-order crossings of [running] orders and the critical
    speeds (`running.campbell`)."""
    from rich.table import Table

    from beltdyn.analysis.running import campbell, speed_axis

    if not speed_axis(result):
        return
    names = [p.name for p in cfg.pulleys]
    spans = [f"{names[i]}-{names[(i + 1) % len(names)]}" for i in range(len(names))]
    orders = cfg.running.orders if cfg.running is not None else ()
    crossings, unstable = campbell(result, orders, spans)
    if orders:
        t = Table(title=f"Campbell diagram: crossings of the modes with the engine orders {', '.join(f'{k:g}' for k in orders)}")
        for col in ("order", "driver speed (rad/s)", "(rpm)", "belt speed (m/s)", "frequency (Hz)", "mode"):
            t.add_column(col, justify="left" if col == "mode" else "right")
        for x in crossings:
            t.add_row(f"{x.order:g}", f"{x.driver_speed:.2f}", f"{x.driver_speed * 30 / 3.141592653589793:.0f}",
                      f"{x.belt_speed:.3f}", f"{x.frequency:.3f}", f"{x.mode + 1}: {x.label}")
        if not crossings:
            t.add_row("", "", "", "", "", "no crossing in the swept range")
        con.print(t)
    for x in unstable:
        con.print(f"[bold yellow]{x.kind}:[/] mode {x.mode + 1} ({x.label}) at the critical driver speed "
                  f"{x.driver_speed:.4g} rad/s (belt speed {x.belt_speed:.4g} m/s)")



def print_ladder(choice) -> None:
    from rich.table import Table

    con = console()
    tbl = Table(title=f"Span models for the modes below {choice.fmax:g} Hz within rtol = {choice.rtol:g} "
                      f"(cheapest first: spring, string, ANCF)")
    for col in ("span", "model", "elements", "DOFs", "estimated error", "note"):
        tbl.add_column(col, justify="left" if col in ("span", "model", "note") else "right")
    for c in choice.spans:
        tbl.add_row(c.name, c.model, "-" if c.model == "spring" else str(c.elements), str(c.dofs), f"{c.estimate:.1e}",
                    c.note)
    con.print(tbl)
    state = "meets" if choice.met else "does NOT meet"
    con.print(f"the choice {state} rtol = {choice.rtol:g} below {choice.fmax:g} Hz (largest estimate "
              f"{choice.estimate:.2e}, {choice.solves} drive solves); it is the \\[spans] table of the resolved "
              f"configuration in the results file")

def print_unrepresented(job) -> None:
    """The modes the spring spans leave out (`job.unrepresented`), if any."""
    band, lay, modes = job.unrepresented
    if modes:
        text = ", ".join(f"{f:.4g} Hz ({kind} {order}, span {lay.span_name(s)})" for s, kind, order, f in modes)
        console().print(f"[bold yellow]note:[/] the spring spans leave out {len(modes)} mode(s) below {band:.4g} Hz "
                         f"(their own modes, not in the table above): {text}")


def print_transient(con, summary, spans, peaks, f_exc, shown=()) -> None:
    from rich.table import Table

    con.print(f"transient {summary.status}: {plural(summary.steps, 'step')} to t = {summary.final_time:.6g} s "
              f"({summary.newton_iterations / max(summary.steps, 1):.2f} Newton iterations per step), "
              f"{plural(summary.refactorizations, 'refactorization')}, {plural(summary.step_halvings, 'step halving')} "
              f"(smallest step {summary.min_step:.3g} s); energy balance error {summary.energy_error:.2e} "
              f"of the energy moved")
    for w in summary.warnings:
        if w not in shown:  # (those shown before the run are not repeated)
            con.print(f"[bold yellow]warning[/]: {w}")
    ev = summary.slack_events
    for t, s, slack, fmin in ev[:8]:
        con.print(f"  span {spans[int(s)]} {'went slack' if slack else 'taut again'} at t = {t:.6g} s "
                  f"(min axial force {fmin:.4g} N)")
    if len(ev) > 8:
        n_slack = int(ev[:, 2].sum())
        con.print(f"  ... {len(ev)} slack/taut events in all ({n_slack} times a span went slack); "
                  f"all are in /transient/slack_events")
    if not peaks:
        return
    # the largest peaks of each recorded quantity (amplitudes in that quantity's units)
    tbl = Table(title="Dominant spectral peaks" + (f" (excitation {f_exc:g} Hz)" if f_exc else ""))
    for col in ("channel", "frequency (Hz)", "amplitude", "harmonic", "nearest mode (Hz)", "vs mode (%)"):
        tbl.add_column(col, justify="left" if col == "channel" else "right")
    from beltdyn.workflow import shown_peaks

    for _, units, p in shown_peaks(peaks):  # the same rows as /transient/peaks
        tbl.add_row(p.channel, f"{p.frequency:.3f}", f"{p.amplitude:.4g} {units}",
                    str(p.harmonic) if p.harmonic else "-",
                    f"{p.mode_frequency:.3f}" if p.nearest_mode else "-",
                    f"{p.mode_distance_pct:+.2f}" if p.nearest_mode else "-")
    con.print(tbl)

