"""`make bench`: timings and memory of beltdyn against the issues' targets, printed as a table.

Measured here, never in tests. In-process timings are medians over repeats after a warm-up (imports
done); CLI timings are wall-clock medians of whole processes. BLAS runs single-threaded, as in the
CLI (small dense matrices are fastest that way).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper" / "bench_T200.toml"


def median_time(fn, *, repeats: int, warmup: int = 2) -> float:
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def cli_time(args: list[str], repeats: int = 7) -> float:
    exe = shutil.which("beltdyn") or str(Path(sys.executable).parent / "beltdyn")
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run([exe, *args], cwd=tmp, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            times.append(time.perf_counter() - t0)
    return statistics.median(times)


def pipeline(cfg):
    from beltdyn.geometry import layout_from_config
    from beltdyn.modal import solve_modes
    from beltdyn.static import model_from_config, solve_static

    model = model_from_config(cfg, layout_from_config(cfg))
    st = solve_static(cfg, model)
    return model, solve_modes(model, st.q, n_modes=cfg.modal.modes, solver=cfg.modal.solver)


def main() -> None:
    from beltdyn.config import load_config

    rows: list[tuple[str, str, str, str]] = []

    def add(name: str, value: str, target: str, ok: bool | None) -> None:
        rows.append((name, value, target, "" if ok is None else ("ok" if ok else "MISSED")))

    # --- start-up (issue 2) and modal end to end (issue 3)
    t = cli_time(["--help"])
    add("beltdyn --help (process wall)", f"{t * 1e3:.0f} ms", "< 500 ms", t < 0.5)
    t = cli_time(["geometry", str(PAPER), "-o", "g.h5", "--force"])
    add("beltdyn geometry, paper 200 N (process wall)", f"{t * 1e3:.0f} ms", "< 500 ms", t < 0.5)
    t = cli_time(["modal", str(PAPER), "-o", "m.h5", "--force"])
    add("beltdyn modal, paper 200 N, start to HDF5 written", f"{t * 1e3:.0f} ms", "< 800 ms", t < 0.8)

    # --- static + modal in process (issue 3): full pipeline from the config object
    targets = {10: 3e-3, 40: 10e-3, 160: 60e-3}
    for n_el, target in targets.items():
        cfg = load_config(PAPER, [f"mesh.elements_per_span={n_el}"])
        model, modes = pipeline(cfg)
        t = median_time(lambda: pipeline(cfg), repeats=30 if n_el < 100 else 10)
        add(f"static + modal, {n_el} el/span ({model.n_dof} DOFs, {len(modes.frequency)} modes, {modes.solver})",
            f"{t * 1e3:.2f} ms", f"<= {target * 1e3:.0f} ms", t <= target)

    # --- memory against mesh size: peak traced allocation of the pipeline per DOF
    per_dof = []
    for n_el in (10, 40, 160, 400):
        cfg = load_config(PAPER, [f"mesh.elements_per_span={n_el}"])
        pipeline(cfg)
        tracemalloc.start()
        model, _ = pipeline(cfg)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        per_dof.append(peak / model.n_dof)
        add(f"peak memory, {n_el} el/span ({model.n_dof} DOFs)", f"{peak / 1e6:.2f} MB ({peak / model.n_dof / 1e3:.1f} kB/DOF)",
            "linear in DOFs", None)
    growth = per_dof[-1] / per_dof[1]
    add("memory per DOF, 400 vs 40 el/span", f"x {growth:.2f}", "~ constant (linear growth)", growth < 2.0)

    width = [max(len(r[i]) for r in rows + [("benchmark", "measured", "target", "")]) for i in range(4)]
    line = "  ".join("{:<%d}" % w for w in width)
    print(line.format("benchmark", "measured", "target", ""))
    print(line.format(*("-" * w for w in width)))
    for r in rows:
        print(line.format(*r))


if __name__ == "__main__":
    main()
