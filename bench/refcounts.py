"""The compiled stepper's reference counts per step, by the array they count (issue 24's transient speed).

numba's runtime counts references to every array the compiled code holds; beltdyn compiles with numba's
public options only, so the stepper pays an atomic increment and decrement per array each time an inlined
part takes it as an argument, or a function that passes arrays on to another takes it (numba's pruner
removes the rest). This script counts them: it runs a short transient twice (N and 2 N steps) with numba's
public debug switch NUMBA_DEBUG_NRT=1, in a cache folder of its own (the debug build prints from every
count: it must not land in the package's cache), and prints the counts per step, grouped by the part of
`StepperModel` (or the scratch, the state, ...) whose array they count.

The arrays are named by the order in which `advance` takes its arguments on entry (numba counts each
array argument once there, in order): an observation of numba's code generation used for naming only;
the totals do not depend on it. Measurement only, never a test.

    python bench/refcounts.py                   # the paper bench, 10 elements a span
    python bench/refcounts.py --drive spring    # the FEAD example with every span a spring, rigid wraps
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MARK, END = "=== refcounts: counting", "=== refcounts: done"

# the run inside the debug process: a warm-up transient, then the counted one between the marks
CHILD = r'''
import os, sys
import numpy as np
from beltdyn.config import load_config
from beltdyn.pipeline import analyse
import beltdyn.analysis.integrator as itg
from beltdyn.analysis.transient import run_transient

drive, steps = sys.argv[1], int(sys.argv[2])
root = sys.argv[3]
common = ["transient.step=1e-4", "transient.output_interval=1e-2", "transient.spectrum.enabled=false"]
if drive == "paper":
    path = root + "/configs/examples/bench_transient_small.toml"
    over = ["mesh.elements_per_span=10"] + common
else:
    path = root + "/configs/examples/fead_4cyl.toml"
    over = [f'spans.{n}.model="spring"' for n in load_config(path).span_names] + ['belt.wraps="rigid"'] + common
names, seen = [], []

def flatten(obj, prefix):
    if isinstance(obj, np.ndarray):
        names.append(prefix)
    elif isinstance(obj, tuple):
        for field, value in zip(getattr(obj, "_fields", None) or range(len(obj)), obj):
            flatten(value, f"{prefix}.{field}")

class Named:  # names the arrays of the first STEP call (advance's arguments, in order)
    def __init__(self, kernel):
        self.kernel = kernel
    def __call__(self, *args):
        if args[0] == itg.STEP and not seen:
            for label, value in zip(("task", "state", "model", "opts", "fac", "fresh", "out", "ev", "info",
                                     "work"), args):
                flatten(value, label)
            seen.append(True)
            sys.stdout.flush()
            os.write(1, b"=== refcounts: first step call\n")
        return self.kernel(*args)

itg.advance = Named(itg.advance)
warm = load_config(path, over + ["transient.duration=1e-3"])
run = analyse(warm, compiled=True)
run_transient(run.system, run.static, warm.transient, sink=lambda t, b: None)
seen.clear(); names.clear()
cfg = load_config(path, over + [f"transient.duration={steps * 1e-4}"])
sys.stdout.flush(); os.write(1, b"''' + MARK + r'''\n")
run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: None)
sys.stdout.flush(); os.write(1, ("''' + END + r''' " + " ".join(names) + "\n").encode())
'''


def group_of(name: str) -> str:
    """The part an array belongs to: model.<part>.<field> -> model.<part>.<field>, work.vec -> work.vec, ..."""
    parts = name.split(".")
    return ".".join(parts[:3] if parts[0] == "model" else parts[:2])


def counted(drive: str, steps: int, cache: str) -> collections.Counter:
    """Reference increments of a transient of `steps` steps, by the part whose array they count (a
    process's pointers are its own: the runs are compared by name)."""
    env = dict(os.environ, NUMBA_DEBUG_NRT="1", NUMBA_CACHE_DIR=cache, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", CHILD, drive, str(steps), str(ROOT)], env=env, cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout.split("\n")
    start = out.index(MARK)
    stop = next(i for i, line in enumerate(out) if line.startswith(END))
    names = out[stop].split()[3:]
    body = out[start + 1:stop]
    first = body.index("=== refcounts: first step call")
    pointer = re.compile(r"NRT_Incref \d+ \[(0x[0-9a-f]+)\]")
    entry = [m.group(1) for m in map(pointer.search, body[first:]) if m][:len(names)]
    name_of = {p: n for n, p in reversed(list(zip(names, entry)))}  # several arrays may share a pointer
    groups = collections.Counter()
    for m in map(pointer.search, body):
        if m:
            groups[group_of(name_of.get(m.group(1), "(made inside the stepper)"))] += 1
    return groups


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--drive", choices=("paper", "spring"), default="paper")
    parser.add_argument("--steps", type=int, default=100)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="beltdyn-refcounts-") as cache:
        print(f"compiling the stepper with NUMBA_DEBUG_NRT=1 into {cache} (minutes) ...", flush=True)
        short = counted(args.drive, args.steps, cache)
        long = counted(args.drive, 2 * args.steps, cache)
    per_step = {g: (long[g] - short.get(g, 0)) / args.steps for g in long}
    print(f"{args.drive}: {sum(per_step.values()):.1f} reference increments a step (as many decrements)")
    parts = collections.Counter()
    for group, c in per_step.items():
        parts[".".join(group.split(".")[:2] if group.startswith("model.") else group.split(".")[:1])] += c
    print("by part: " + ", ".join(f"{part} {c:.1f}" for part, c in parts.most_common() if c >= 0.05))
    print("by array:")
    for group, c in sorted(per_step.items(), key=lambda item: -item[1]):
        if c >= 0.05:
            print(f"{c:8.1f}  {group}")


if __name__ == "__main__":
    main()
