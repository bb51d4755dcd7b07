"""`make bench-interleave BASE=<rev>`: the speed clause's in-process rows, base and this tree taking turns.

`make bench-compare` runs one tree's `bench/run.py` after the other's; on a shared machine whose wall time
drifts by 10 % within minutes it cannot tell 10 % apart. Here each (tree, case) is a long-lived worker
process (that tree first on its import path, warmed up once; `PROCESSES` of them per tree), and the
workers take turns, round after round: drift reaches both trees alike. Each turn times `TRIES` runs of the
case and reports the fastest; the table gives, per case, the minimum and the 10th percentile over the
rounds and the ratio of the minima. The other commit is checked out into a temporary git worktree (its
kernels compile once there).

The static rows run the base twice: as it is, and with its module-level memos emptied before each run
("base, cold": what a process that analyses the configuration once pays). The redesign (issue 24) removed
those memos (`_DOFMAPS` of the DOF maps, `_PATTERNS` of the sparse patterns, `_no_elements`' cache, the
configuration's cached properties), which served a loop re-analysing one configuration, as these rows do,
from the first run's work; this tree has none to empty. A tree without them is unaffected (the names are
looked up, not required). This tree's static rows run twice too: as they are, and "shared": every run of
the worker handed one `model.reuse.Reuse`, as a study's analyses of one drive are (a sweep's chunk, the fit,
the refinement): the explicit store that took the memos' place, to set against the base as it is.

    python bench/interleave.py BASE_REV [ROUNDS]
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

from compare import warm_up  # bench/compare.py (this script's folder is first on the import path)

ROOT = Path(__file__).resolve().parents[1]
TRIES = {"transient": 1, "static": 10}  # runs per turn: the fastest is the turn's time

# (name, kind, configuration, its overrides, rigid wraps: "belt.wraps" (this key exists since issue 25))
CASES = (
    ("transient 1 s at dt = 1e-4 s, paper bench 10 el/span", "transient", "configs/examples/bench_transient_small.toml",
     ("mesh.elements_per_span=10",), False),
    ("transient 1 s at dt = 1e-4 s, all-spring FEAD, rigid wraps", "transient", "configs/examples/fead_4cyl.toml",
     ("spring",), True),
    ("transient 1 s at dt = 1e-4 s, FEAD example, rigid wraps", "transient", "configs/examples/fead_4cyl.toml", (),
     True),
    ("static + modal, paper 10 el/span", "static", "configs/paper/bench_T200.toml", ("mesh.elements_per_span=10",),
     False),
    ("static + modal, paper 40 el/span", "static", "configs/paper/bench_T200.toml", ("mesh.elements_per_span=40",),
     False),
    ("static + modal, paper 160 el/span", "static", "configs/paper/bench_T200.toml", ("mesh.elements_per_span=160",),
     False),
    ("static + modal, FEAD example, rigid wraps", "static", "configs/examples/fead_4cyl.toml", (), True),
    ("static + modal, all-spring FEAD, rigid wraps", "static", "configs/examples/fead_4cyl.toml", ("spring",), True),
)

PROCESSES = 3  # workers per tree and case (measured: one process's minimum of the 160 el/span row lies up to 15 %
# from another's of the same tree, cause not found; the row takes the fastest of three)
WARM_SECONDS = 3.0  # each worker runs its case this long before the first turn (measured: the first second slower)

# the worker: python -c WORKER tree kind config rigid mode override...; mode: "as-is", "cold" or "shared" (the
# module docstring); a line per turn (the runs to time), answered by the fastest run's seconds
WORKER = r'''
import functools, sys, time
WARM_SECONDS = %r
tree, kind, config, rigid, mode, over = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4] == "1", sys.argv[5], \
    sys.argv[6:]
cold = mode == "cold"
sys.path.insert(0, tree)
from pathlib import Path
from beltdyn.config import load_config
from beltdyn.pipeline import analyse
layered = (Path(tree) / "beltdyn" / "model").is_dir()  # (the package before its sub-packages: the base)
if layered:
    from beltdyn.analysis.transient import run_transient
else:
    from beltdyn.transient import run_transient
path = str(Path(tree) / config)
if "spring" in over:  # every span a spring span
    over = [o for o in over if o != "spring"] + [f'spans.{n}.model="spring"' for n in load_config(path).span_names]
if rigid and layered:
    over = over + ['belt.wraps="rigid"']
if kind == "transient":
    over = over + ["transient.duration=1.0", "transient.step=1e-4", "transient.output_interval=1e-3",
                   "transient.spectrum.enabled=false"]
cfg = load_config(path, over)
if kind == "transient":
    run = analyse(cfg, compiled=True)
    case = lambda: run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: None)
elif mode == "shared":
    from beltdyn.model.reuse import Reuse
    reuse = Reuse()
    case = lambda: analyse(cfg, modal=True, reuse=reuse)
else:
    case = lambda: analyse(cfg, modal=True)


def forget():
    """The base's module-level memos emptied, and the configuration's cached properties (cold: before each
    run; the module docstring)."""
    if not cold:
        return
    for name, attr in vars(type(cfg)).items():
        if isinstance(attr, functools.cached_property):
            cfg.__dict__.pop(name, None)
    for mod in list(sys.modules.values()):
        if getattr(mod, "__name__", "").startswith("beltdyn"):
            for memo in (getattr(mod, "_DOFMAPS", None), getattr(mod, "_PATTERNS", None)):
                if isinstance(memo, dict):
                    memo.clear()
            if hasattr(getattr(mod, "_no_elements", None), "cache_clear"):
                mod._no_elements.cache_clear()


warm = time.perf_counter() + WARM_SECONDS  # caches, page faults, the clock: a few runs are slower at first
while True:
    forget()
    case()
    if time.perf_counter() > warm:
        break
print("ready", flush=True)
for line in sys.stdin:
    best = float("inf")
    for _ in range(int(line)):
        forget()
        t0 = time.perf_counter()
        case()
        best = min(best, time.perf_counter() - t0)
    print(f"{best:.9f}", flush=True)
'''


def start(tree: Path, case: tuple, mode: str = "as-is") -> subprocess.Popen:
    """A warmed-up worker of `case` on `tree` (its first line "ready"); mode "cold": the tree's module-level
    memos emptied before each run, "shared": its runs share one `Reuse` (the module docstring)."""
    _, kind, config, over, rigid = case
    args = [str(tree), kind, config, "1" if rigid else "0", mode, *over]
    proc = subprocess.Popen([sys.executable, "-c", WORKER % WARM_SECONDS, *args], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, cwd=tree)
    if proc.stdout.readline().strip() != "ready":
        raise SystemExit(f"the worker of {case[0]!r} on {tree} failed")
    return proc


def turn(proc: subprocess.Popen, tries: int) -> float:
    proc.stdin.write(f"{tries}\n")
    proc.stdin.flush()
    return float(proc.stdout.readline())


def measure(trees: tuple[Path, Path], rounds: int) -> list[tuple[str, list[float], ...]]:
    """Per case: (name, base times, the cold base's times, this tree's times, this tree's shared times; the
    static rows' only, else empty): each of PROCESSES workers per tree and mode a time per round, all workers
    taking turns."""
    rows = []
    for case in CASES:
        static = case[1] == "static"
        runs = [(trees[0], m) for m in (("as-is", "cold") if static else ("as-is",))] + \
            [(trees[1], m) for m in (("as-is", "shared") if static else ("as-is",))]
        workers = [(k, start(tree, case, mode)) for _ in range(PROCESSES) for k, (tree, mode) in enumerate(runs)]
        times: list[list[float]] = [[] for _ in runs]
        try:
            for r in range(rounds):
                for i in range(len(workers)):  # who goes first rotates too
                    k, proc = workers[(r + i) % len(workers)]
                    times[k].append(turn(proc, TRIES[case[1]]))
        finally:
            for _, proc in workers:
                proc.stdin.close()
                proc.wait()
        rows.append((case[0], *times) if static else (case[0], times[0], [], times[1], []))
        print(f"  {case[0]}: done", file=sys.stderr, flush=True)
    return rows


def main() -> None:
    if len(sys.argv) not in (2, 3):
        raise SystemExit("usage: python bench/interleave.py BASE_REV [ROUNDS]")
    base_rev, rounds = sys.argv[1], int(sys.argv[2]) if len(sys.argv) == 3 else 30
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(base), base_rev], check=True)
        try:
            for tree in (base, ROOT):
                warm_up(tree)  # (the kernels compiled first: a compile just before a case slows its first rounds)
            rows = measure((base, ROOT), rounds)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)], check=False)
    width = max(len(name) for name, *_ in rows)
    print(f"{'benchmark (interleaved, ' + str(rounds) + ' rounds)':<{width}}  {'base ' + base_rev[:10]:>22}  "
          f"{'base, cold':>22}  {'this tree':>22}  {'this tree, shared':>22}  {'ratio':>6}  {'to cold':>7}  "
          f"{'shared':>6}")
    for name, b, c, a, s in rows:
        b, c, a, s = sorted(b), sorted(c), sorted(a), sorted(s)
        p10 = len(b) // 10
        cell = lambda t: f"{t[0] * 1e3:9.2f} ms (p10 {t[p10] * 1e3:.2f})" if t else ""  # noqa: E731
        ratio = lambda x, y: f"{x[0] / y[0]:.2f}" if x and y else ""  # noqa: E731
        print(f"{name:<{width}}  {cell(b):>22}  {cell(c):>22}  {cell(a):>22}  {cell(s):>22}  {ratio(a, b):>6}  "
              f"{ratio(a, c):>7}  {ratio(s, b):>6}")


if __name__ == "__main__":
    main()
