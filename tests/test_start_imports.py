"""What the transient command's start-up imports: scipy.interpolate (order tracking, ~0.3 s of a short
`beltdyn transient` on a quiet machine) only when a run tracks orders."""

import subprocess
import sys
from pathlib import Path


def test_the_cli_and_the_transient_workflow_do_not_import_scipy_interpolate():
    # a fresh interpreter: the test session itself may have imported it already
    code = ("import sys; import beltdyn.cli.main, beltdyn.workflow, beltdyn.analysis.transient; "
            "print('scipy.interpolate' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


def test_order_tracking_still_imports_it_when_asked():
    code = ("import sys; from beltdyn.analysis.orders import order_tracking; "
            "print('scipy.interpolate' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "True"


def _fresh(code: str) -> str:
    """stdout of `code` run by a fresh interpreter (the test session has imported everything already)."""
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()


def test_the_cli_module_imports_nothing_heavy():
    # `beltdyn --help` imports beltdyn.cli.main and no more: each of these costs 50-450 ms of process time
    code = ("import sys, beltdyn.cli.main; "
            "print([m for m in ('numpy', 'numba', 'scipy', 'h5py', 'pydantic', 'matplotlib') if m in sys.modules])")
    assert _fresh(code) == "[]"


def test_beltdyn_geometry_imports_neither_numba_nor_scipy(tmp_path):
    # numba's import alone is ~0.4 s of process time; the geometry command's target is < 500 ms in all
    paper = Path(__file__).resolve().parents[1] / "configs" / "paper" / "bench_T200.toml"
    code = ("import sys\nfrom beltdyn.cli import app\n"
            f"try:\n    app(['geometry', {str(paper)!r}, '-o', {str(tmp_path / 'g.h5')!r}, '--force'])\n"
            "except SystemExit as exc:\n    assert not exc.code, exc.code\n"
            "print([m for m in ('numba', 'scipy', 'matplotlib') if m in sys.modules])")
    assert _fresh(code).splitlines()[-1] == "[]"  # (after the command's own output)
    assert (tmp_path / "g.h5").is_file()


def test_importing_the_cli_leaves_the_garbage_collector_alone_the_console_script_raises_its_threshold():
    code = ("import gc\nbefore = gc.get_threshold()\nimport beltdyn.cli, beltdyn.cli.main\n"
            "print(gc.get_threshold() == before, beltdyn.cli.app is beltdyn.cli.main.app)")
    assert _fresh(code) == "True True"
    # the console script (`beltdyn.cli:run`): the threshold raised before typer, rich and the commands are
    # imported, so `beltdyn --help` runs without one collection (with Python's 700 there until `run`: ~22)
    code = ("import gc, sys\nimport beltdyn.cli\nfrom beltdyn import cleanup\nseen = []\n"
            "gc.callbacks.append(lambda phase, info: seen.append(info['generation']) if phase == 'start' else None)\n"
            "cleanup.at_exit(lambda: print('typer' in sys.modules, gc.get_threshold()[0] == beltdyn.cli.GC_YOUNG, "
            "seen, flush=True))\n"
            "sys.argv = ['beltdyn', '--help']\nbeltdyn.cli.run()\n")
    assert _fresh(code).splitlines()[-1] == "True True []"


def test_the_transient_command_path_imports_neither_scipy_signal_nor_matplotlib():
    # the spectra import scipy.signal when a run computes them (measured in a 10 el/span, 10 ms `beltdyn
    # transient` without spectra: neither module loaded, as in the base bca9ecb); matplotlib only `beltdyn plot`
    code = ("import sys, beltdyn.cli.main, beltdyn.cli.commands.transient, beltdyn.workflow, "
            "beltdyn.analysis.transient, beltdyn.results.io; "
            "print([m for m in ('scipy.signal', 'matplotlib') if m in sys.modules])")
    assert _fresh(code) == "[]"
