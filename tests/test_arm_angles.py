"""Angles are directions (issue 26, item 3): the L0 fit of a tensioner arm, its stops and every reported
arm angle on one branch near the drawing, and an arm's offsets in rad (or deg), never in m.

Through the real CLI: the tensioner of `fead_4cyl.toml` drawn at 172 deg instead of 180 deg, on the same
circle about its pivot (|centre - pivot| = 0.08 m both ways, to 4.2e-7 m: the issue's rounded centre), so
that the fitted arm, a physical position, is the same whichever drawing it starts from (to what the
4.2e-7 m of arm length move: below 1e-3 deg): the drawing at 180 deg is the independent reference. Before the fix the fit from 172 deg landed on 204.729 rad (the right 210.1 deg plus 32
turns) and refused it against stops [3.3, 4.1] rad that contain the physical angle.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"
EXE = str(Path(sys.executable).parent / "beltdyn")
AT_172 = "pulleys.TEN.center=[0.105779, 0.363134]"  # the pivot (0.185, 0.352) + 0.08 m at 172 deg
PIVOT = (0.185, 0.352)
STOPS = (3.3, 4.1)  # rad, fead_4cyl.toml's arm_range of TEN


def _run(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *args], cwd=tmp_path, capture_output=True, text=True, timeout=300)


def _drawn(center) -> float:
    return math.atan2(center[1] - PIVOT[1], center[0] - PIVOT[0])


def test_the_drawing_at_172_deg_is_on_the_arm_circle():
    # (the premise of the comparisons below: both drawings 0.08 m from the pivot)
    assert math.hypot(0.105779 - PIVOT[0], 0.363134 - PIVOT[1]) == pytest.approx(0.08, abs=5e-7)
    assert math.degrees(_drawn((0.105779, 0.363134))) == pytest.approx(172.0, abs=1e-3)


def test_geometry_fits_the_arm_between_its_stops_from_a_drawing_at_172_deg(tmp_path):
    turned = {}
    for name, sets in (("172", ["--set", AT_172]), ("180", [])):
        r = _run(tmp_path, "geometry", str(FEAD), *sets, "-o", f"g{name}.h5", "--force")
        assert r.returncode == 0, r.stderr
        m = re.search(r"the arm of pulley TEN turned (-?[0-9.]+) deg", r.stdout)
        assert m, r.stdout
        turned[name] = float(m.group(1))
        assert -180.0 <= turned[name] < 180.0  # a turn is a direction change: never whole turns
    fitted_172 = math.degrees(_drawn((0.105779, 0.363134))) + turned["172"]
    fitted_180 = 180.0 + turned["180"]  # (drawn at (0.105, 0.352): exactly -x from the pivot)
    assert fitted_172 == pytest.approx(fitted_180, abs=1e-3)  # one physical position (printed to 1e-4 deg)
    assert math.degrees(STOPS[0]) <= fitted_172 <= math.degrees(STOPS[1])
    assert fitted_172 == pytest.approx(210.1, abs=0.05)  # the right answer


def test_static_reports_the_arm_near_the_drawing_from_172_deg(tmp_path):
    out = {}
    for name, sets in (("172", ["--set", AT_172]), ("180", [])):
        r = _run(tmp_path, "static", str(FEAD), *sets, "-o", f"s{name}.h5", "--force")
        assert r.returncode == 0, r.stderr
        m = re.search(r"the arm of pulley TEN turned (-?[0-9.]+) deg", r.stdout)
        assert m and -180.0 <= float(m.group(1)) < 180.0, r.stdout
        with h5py.File(tmp_path / f"s{name}.h5") as f:
            g = f["static"]
            names = [x.decode() if isinstance(x, bytes) else str(x) for x in g["pulley"][()]]
            j = names.index("TEN")
            assert g["adjust_offset"].attrs["units"] == "rad"
            out[name] = (float(g["arm_angle"][j]), float(g["adjust_offset"][()]), float(g["mean_tension"][()]))
    for name, (phi, offset, _) in out.items():
        assert STOPS[0] <= phi <= STOPS[1], name  # the reported angle on the stops' branch, between them
        assert -math.pi <= offset < math.pi, name
    drawn_172 = _drawn((0.105779, 0.363134))
    assert drawn_172 + out["172"][1] == pytest.approx(out["172"][0], abs=1e-9)  # offset = the turn from the drawing
    # the same drive (the same circle): the same equilibrium within the static tolerance
    assert out["172"][0] == pytest.approx(out["180"][0], abs=1e-4)
    assert out["172"][2] == pytest.approx(out["180"][2], rel=1e-5)


@pytest.mark.parametrize("length, word", [(1.5, "short"), (2.5, "long")])
def test_an_arm_that_cannot_fit_names_its_offset_in_rad(tmp_path, length, word):
    r = _run(tmp_path, "geometry", str(FEAD), "--set", f"belt.length={length}", "-o", "g.h5", "--force")
    assert r.returncode == 2
    msg = r.stderr.strip() or r.stdout.strip()
    assert "belt.length" in msg and f"too {word}" in msg and "Traceback" not in msg
    m = re.search(r"at offset (-?[0-9.e+-]+) (\w+)\)", msg)
    assert m, msg
    assert m.group(2) == "rad"
    assert -math.pi <= float(m.group(1)) < math.pi


def test_the_fit_turn_is_wrapped_from_any_drawing_on_the_circle():
    # In process: fit_adjustable from drawings all around the arm circle that the belt path admits; every
    # fit lands on the one physical arm position (that of the 180 deg drawing), its turn in [-pi, pi).
    from beltdyn.config import load_config
    from beltdyn.model.geometry import arm_angle, layout_from_config

    ref = layout_from_config(load_config(FEAD))
    j = ref.names.index("TEN")
    target = arm_angle(ref, j, PIVOT)
    landed = 0
    for deg in np.arange(150.0, 231.0, 10.0):
        c = (PIVOT[0] + 0.08 * math.cos(math.radians(deg)), PIVOT[1] + 0.08 * math.sin(math.radians(deg)))
        try:
            lay = layout_from_config(load_config(FEAD, [f"pulleys.TEN.center=[{c[0]!r}, {c[1]!r}]"]))
        except Exception as exc:  # a drawing whose own path the checks refuse (named, exit 2 in the CLI)
            assert "pulleys" in str(exc), exc
            continue
        landed += 1
        assert -math.pi <= lay.adjust_offset < math.pi
        turned = math.radians(deg) + lay.adjust_offset
        assert math.remainder(turned - target, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
        assert turned == pytest.approx(target if target > 0 else target + 2 * math.pi, abs=1e-9)
    assert landed >= 5
