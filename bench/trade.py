"""`make trade`: the speed/accuracy trade, measured, written into the README between markers.

Knobs a user turns: the mesh (elements per span), the model fidelity (bending on or off:
curvature "linear" or "none"; the fidelity ladder of the spans: spring, string, ANCF, chosen span by
span), and the transient time step. For each: the error against a converged
reference and the wall time; for the step also its frequency error against f dt, measured on the bench's
modes beside the formula of beltdyn.analysis.timestep. Usage: python bench/trade.py README.md
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import re  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper"
START, END = "<!-- trade:start -->", "<!-- trade:end -->"


def timed(fn, repeats=5):
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


def modal_run(cfg, n_modes):
    from beltdyn.pipeline import analyse

    return analyse(cfg, modal=True, n_modes=n_modes).modal


def keyed(md):
    return {(md.kind[k], int(md.order[k]), int(md.span[k])): md.frequency[k] for k in range(len(md.frequency))}


def mesh_table(n_modes: int = 12) -> list[str]:
    from beltdyn.config import load_config
    from beltdyn.study.sweep import richardson

    base = load_config(PAPER / "bench_T200.toml")
    ref = modal_run(load_config(PAPER / "bench_T200.toml", ["mesh.elements_per_span=320"]), n_modes + 8)
    ref_keys = list(keyed(ref))[:n_modes]
    ref_f = np.array([keyed(ref)[k] for k in ref_keys])
    meshes = [2, 3, 4, 6, 8, 12, 16, 24, 32, 64]
    rows, freqs = [], []
    for n_el in meshes:
        cfg = load_config(PAPER / "bench_T200.toml", [f"mesh.elements_per_span={n_el}"])
        md, t = timed(lambda: modal_run(cfg, n_modes + 8))
        kd = keyed(md)
        f = np.array([kd.get(k, np.nan) for k in ref_keys])
        freqs.append(f)
        rows.append((n_el, t, f))
    f_all = np.array(freqs)
    est = np.full_like(f_all, np.nan)
    for i in range(2, len(meshes)):
        sub = f_all[: i + 1]
        if np.all(np.isfinite(sub[-3:])):
            est[i] = richardson(sub, np.array(meshes[: i + 1], dtype=float))[1][-1]
    lines = [f"Mesh (paper bench, T = 200 N; the {n_modes} lowest modes against 320 elements per span):", "",
             "| el/span | DOFs | max error, 12 modes | max Richardson estimate | static + modal wall |",
             "|---:|---:|---:|---:|---:|"]
    for i, (n_el, t, f) in enumerate(rows):
        err = np.abs(f - ref_f) / ref_f
        e_txt = f"{np.nanmax(err):.1e}" if np.all(np.isfinite(err)) else f"{np.nanmax(err):.1e} (a mode missing)"
        s_txt = f"{np.nanmax(est[i]):.1e}" if np.all(np.isfinite(est[i])) else "-"
        lines.append(f"| {n_el} | {8 * n_el + 3} | {e_txt} | {s_txt} | {t * 1e3:.2f} ms |")
    return lines


def bending_table() -> list[str]:
    from beltdyn.config import load_config

    lines = ["", "Model fidelity: bending on (curvature \"linear\", paper Eq. 17) or off (a string, \"none\"), "
             "10 el/span, 8 lowest modes matched by kind and order:", "",
             "| EI (N m^2) | bending | max change of the 8 modes | static + modal wall |", "|---:|---|---:|---:|"]
    for EI in (0.02, 1.0, 100.0):
        runs = {}
        for curv in ("linear", "none"):
            cfg = load_config(PAPER / "bench_T200.toml", [f"belt.EI={EI}", f"model.curvature={curv}"])
            md, t = timed(lambda: modal_run(cfg, 16))
            runs[curv] = (keyed(md), t)
        keys = [k for k in list(runs["linear"][0])[:8]]
        diffs = [abs(runs["none"][0].get(k, np.nan) - runs["linear"][0][k]) / runs["linear"][0][k] for k in keys]
        d = np.nanmax(diffs) if np.any(np.isfinite(diffs)) else np.nan
        lines.append(f"| {EI:g} | linear | reference | {runs['linear'][1] * 1e3:.2f} ms |")
        lines.append(f"| {EI:g} | none | {100 * d:.2f} % | {runs['none'][1] * 1e3:.2f} ms |")
    return lines


def step_table() -> list[str]:
    sys.path.insert(0, str(ROOT / "bench"))
    from run import step_study

    lines = ["", "Transient time step (bearing force on A, 0.2 s of a 45 Hz rotation of C, rho_inf = 1), against "
             "dt = 3.125e-6 s:", "", "| dt (s) | max rel. error | wall |", "|---:|---:|---:|"]
    for dt, err, wall in step_study():
        lines.append(f"| {dt} | {err} | {wall} |")
    return lines


def frequency_table(rho_inf: float = 0.9) -> list[str]:
    """The step's frequency error: measured on the paper bench's own modes through the nonlinear
    production transient (free vibration along one mode, tests/test_timestep.bench_mode_errors) beside
    the exact formula of beltdyn.analysis.timestep and its series."""
    import math

    sys.path.insert(0, str(ROOT / "tests"))
    from test_timestep import bench_mode_errors

    from beltdyn.analysis.timestep import frequency_error, resolved_band, series_coefficient

    c = series_coefficient(rho_inf)
    rows = []
    for dt in (1e-4, 4e-4, 1e-3):
        rows += [(f * dt, f, dt, err) for f, err in bench_mode_errors(dt, [0, 4, 11], rho_inf)]
    e190, e300 = frequency_error([190.0, 300.0], 1e-4, rho_inf)
    lines = ["", f"Transient frequency error e = f_numerical / f - 1 against f dt (generalized-alpha, rho_inf = "
             f"{rho_inf}): measured on the paper bench's modes (free vibration along one mode through the "
             f"nonlinear transient, the phase advance per step of the modal coordinate) beside the exact formula "
             f"of beltdyn.analysis.timestep and its series -{c:.4f} (2 pi f dt)^2 (transient.accuracy and transient.fmax "
             f"choose the step from it). At dt = 1e-4 s: {e190:+.3%} at 190 Hz, {e300:+.3%} at 300 Hz, "
             f"|e| <= 1e-3 up to {resolved_band(1e-4, 1e-3, rho_inf):.0f} Hz.", "",
             "| f dt | mode | dt (s) | measured | formula | series |", "|---:|---:|---:|---:|---:|---:|"]
    for fdt, f, dt, err in sorted(rows):
        Om = 2 * math.pi * fdt
        lines.append(f"| {fdt:.4f} | {f:.1f} Hz | {dt:g} | {err:+.4e} | {frequency_error(f, dt, rho_inf):+.4e} | "
                     f"{-c * Om * Om:+.4e} |")
    return lines


LADDER_CASES = (("FEAD example", ROOT / "configs" / "examples" / "fead_4cyl.toml", 300.0),
                ("paper bench (T = 200 N, with the transient of bench_transient_small)",
                 ROOT / "configs" / "examples" / "bench_transient_small.toml", 300.0))


def match_modes(md, ref, fmax: float) -> tuple[int, float]:
    """(reference modes below fmax that `md` lacks, worst relative error of the others): matched by
    kind, order and span, else by the nearest unmatched frequency within 5 %."""
    f_ref = {k: f for k, f in keyed(ref).items() if f <= fmax}
    got = keyed(md)
    free = dict(got)
    errs, missing = [], 0
    for k, f in f_ref.items():
        if k in free:
            errs.append(abs(free.pop(k) / f - 1.0))
            continue
        near = min(free.items(), key=lambda kv: abs(kv[1] - f), default=None)
        if near is not None and abs(near[1] / f - 1.0) < 0.05:
            errs.append(abs(near[1] / f - 1.0))
            free.pop(near[0])
        else:
            missing += 1
    return missing, max(errs, default=0.0)


def ladder_table(rtol: float = 5e-3, duration: float = 0.2) -> list[str]:
    """Per rung (all spring, the automatic mix, all string, all ANCF at 4/8/16/32 el/span): DOFs, the
    worst error of the modes below fmax against 64 el/span ANCF, static + modal wall, transient wall per
    simulated second (dt = 1e-4 s, `duration` s simulated)."""
    from beltdyn.config import load_config
    from beltdyn.study.fidelity import choose_models
    from beltdyn.pipeline import analyse
    from beltdyn.analysis.transient import run_transient

    lines = []
    for title, path, fmax in LADDER_CASES:
        base = load_config(path)
        names = base.span_names
        ref = modal_run(load_config(path, ["mesh.elements_per_span=64"]), 60)
        n_modes = int((ref.frequency <= fmax).sum()) + 8
        choice, _ = choose_models(base, fmax=fmax, rtol=rtol)
        mix = ", ".join(f"{c.name} {c.model}{'' if c.model == 'spring' else f' {c.elements}'}" for c in choice.spans)
        rungs = [("all spring", load_config(path, [f'spans.{n}.model="spring"' for n in names])),
                 (f"mixed (--fmax {fmax:g} --rtol {rtol:g}: {mix})", choice.config)]
        for model in ("string", "ancf"):
            for n_el in (4, 8, 16, 32):
                curv = ['model.curvature="none"'] if model == "string" else []
                rungs.append((f"all {'string' if model == 'string' else 'ANCF'}, {n_el} el/span",
                              load_config(path, [f"mesh.elements_per_span={n_el}", *curv])))
        lines += ["", f"Fidelity ladder, {title}: the modes below {fmax:g} Hz against ANCF at 64 el/span "
                      f"({int((ref.frequency <= fmax).sum())} modes); transient at dt = 1e-4 s:", "",
                  "| rung | DOFs | worst error below fmax | static + modal wall | transient wall per simulated s |",
                  "|---|---:|---:|---:|---:|"]
        for name, cfg in rungs:
            md, t = timed(lambda: analyse(cfg, modal=True, n_modes=n_modes))
            missing, err = match_modes(md.modal, ref, fmax)
            err_txt = f"{err:.1e}" + (f" ({missing} modes missing)" if missing else "")
            tcfg = load_config(path, [f"transient.duration={duration}", "transient.spectrum.enabled=false",
                                      "transient.step=1e-4"])
            from dataclasses import replace

            tcfg = replace(tcfg, spans=cfg.spans, mesh=cfg.mesh, model=cfg.model)
            run = analyse(tcfg)
            run_transient(run.system, run.static, tcfg.transient, sink=lambda t, b: None)  # kernels warm
            t0 = time.perf_counter()
            run_transient(run.system, run.static, tcfg.transient, sink=lambda t, b: None)
            per_s = (time.perf_counter() - t0) / duration
            lines.append(f"| {name} | {md.system.n_dof} | {err_txt} | {t * 1e3:.2f} ms | {per_s:.3g} s |")
    return lines


def main() -> None:
    readme = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "README.md"
    lines = mesh_table() + bending_table() + ladder_table() + step_table() + frequency_table()
    block = "\n".join([START, *lines, END])
    print("\n".join(lines))
    text = readme.read_text(encoding="utf-8")
    if START in text and END in text:
        text = re.sub(re.escape(START) + r".*?" + re.escape(END), lambda m: block, text, flags=re.S)
    else:
        text = text.rstrip() + "\n\n## The speed/accuracy trade (`make trade`)\n\n" + block + "\n"
    readme.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
