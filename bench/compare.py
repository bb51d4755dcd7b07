"""`make bench-compare BASE=<rev>`: `make bench` of this tree and of another commit, side by side.

The other commit is checked out into a temporary git worktree; each tree's own `bench/run.py` runs in
its own process with that tree first on the import path (the same venv, the same machine, one run
after the other, each after its numba warm-up), and the two tables are joined by benchmark name.
Rows that only one tree has are listed with the other side empty. Times are parsed from the
"measured" column (its first number and unit); the last column is this tree over the base.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_UNIT = {"us": 1e-6, "ms": 1e-3, "s": 1.0, "MB": 1.0, "kB": 1e-3}
_VALUE = re.compile(r"([0-9.]+(?:e[-+]?\d+)?)\s*(us|ms|s|MB|kB)\b")


def warm_up(tree: Path) -> None:
    """Compile and cache the kernels of `tree` (numba's cache in its package folder), before anything is timed."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    subprocess.run([sys.executable, "-c", "from beltdyn.pipeline import warm_up; warm_up()"], cwd=tree, env=env,
                   check=False, capture_output=True)
    subprocess.run([sys.executable, "-c", "from beltdyn.transient import warm_up; warm_up()"], cwd=tree, env=env,
                   check=False, capture_output=True)  # (the layout before the sub-packages)


def run_bench(tree: Path) -> str:
    """The table `bench/run.py` of `tree` prints, run with `tree` first on the import path."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    warm_up(tree)
    done = subprocess.run([sys.executable, str(tree / "bench" / "run.py")], cwd=tree, env=env, text=True,
                          capture_output=True)
    if done.returncode:
        raise SystemExit(f"bench/run.py of {tree} failed:\n{done.stderr[-2000:]}")
    return done.stdout


def parse(table: str) -> dict[str, str]:
    """{benchmark: measured} from the first table (columns separated by two or more spaces)."""
    rows: dict[str, str] = {}
    lines = table.splitlines()
    for line in lines[2:]:
        if not line.strip():
            break
        cols = re.split(r"\s{2,}", line.strip())
        if len(cols) >= 2:
            rows[cols[0]] = cols[1]
    return rows


def seconds(measured: str) -> float | None:
    m = _VALUE.search(measured)
    return float(m.group(1)) * _UNIT[m.group(2)] if m else None


def main() -> None:
    if len(sys.argv) != 2:
        raise SystemExit("usage: python bench/compare.py BASE_REV")
    base_rev = sys.argv[1]
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(base), base_rev], check=True)
        try:
            before = parse(run_bench(base))
            after = parse(run_bench(ROOT))
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)], check=False)
    names = list(after) + [n for n in before if n not in after]
    width = max(len(n) for n in names)
    print(f"{'benchmark':<{width}}  {'base ' + base_rev[:10]:>28}  {'this tree':>28}  {'ratio':>6}")
    for n in names:
        b, a = before.get(n, ""), after.get(n, "")
        tb, ta = seconds(b), seconds(a)
        ratio = f"{ta / tb:.2f}" if tb and ta else ""
        print(f"{n:<{width}}  {b[:28]:>28}  {a[:28]:>28}  {ratio:>6}")


if __name__ == "__main__":
    main()
