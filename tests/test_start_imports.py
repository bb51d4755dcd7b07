"""What the transient command's start-up imports: scipy.interpolate (order tracking, ~0.3 s of a short
`beltdyn transient` on a quiet machine) only when a run tracks orders."""

import subprocess
import sys


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
