"""Property-based tests over the configuration space (hypothesis): random valid drives either solve
with finite results or fail with exit 1/2 and a one-line named message; random invalid ones exit 2
naming a key; never a traceback, never a NaN in a group marked complete.

The default run draws a small budget (the CLI starts a process per example); `make test-slow` runs
the larger one (marked slow)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

SUPPORTS = ("fixed", "slide", "bearing", "arm")


@st.composite
def drives(draw) -> dict:
    """A drive of 2-6 pulleys on a convex loop (inside pulleys) plus, sometimes, a backside idler
    pushed into the loop between two of them; every support kind; values from tiny to huge; sometimes
    a [spans] table (spring, string or ANCF spans, their own meshes)."""
    n = draw(st.integers(2, 6))
    R0 = draw(st.floats(0.15, 2.0))
    angles = np.sort(np.array([draw(st.floats(0.0, 2 * math.pi)) for _ in range(n)]))
    gaps = np.diff(np.append(angles, angles[0] + 2 * math.pi))
    if gaps.min() < 0.5:  # pulleys too close on the circle: spread them evenly instead
        angles = np.linspace(0.0, 2 * math.pi, n, endpoint=False) + angles[0]
    centres = np.column_stack([R0 * np.cos(angles), R0 * np.sin(angles)])
    chord = min(np.linalg.norm(centres[i] - centres[(i + 1) % n]) for i in range(n)) if n > 2 else 2 * R0
    pulleys = []
    for i in range(n):
        r = draw(st.floats(0.02, 0.3)) * chord
        p = {"name": f"P{i}", "center": [float(c) for c in centres[i]], "radius": r,
             "mass": draw(st.floats(0.01, 50.0)), "inertia": draw(st.floats(1e-6, 1.0))}
        kind = draw(st.sampled_from(SUPPORTS)) if i > 0 else "fixed"
        if kind == "slide":
            p.update(support="slide", slide_direction=[float(np.cos(angles[i])), float(np.sin(angles[i]))],
                     bearing_stiffness=draw(st.floats(1e3, 1e12)))
        elif kind == "bearing":
            p.update(support="bearing", bearing_stiffness=draw(st.floats(1e3, 1e12)))
        elif kind == "arm":
            out = centres[i] / np.linalg.norm(centres[i])
            tang = np.array([-out[1], out[0]])
            arm = draw(st.floats(0.3, 1.5)) * r + r
            p.update(support="arm", arm_pivot=[float(x) for x in centres[i] + arm * tang],
                     arm_stiffness=draw(st.floats(0.5, 1e4)), arm_inertia=draw(st.floats(0.0, 0.01)))
        pulleys.append(p)
    pulleys[0]["driver"] = True
    movable = [i for i, p in enumerate(pulleys) if p.get("support") in ("slide", "arm")]
    raw = {"belt": {"EA": draw(st.floats(1e3, 1e7)), "EI": draw(st.sampled_from([0.0, 1e-6, 0.02, 1.0, 100.0])),
                    "mass_per_length": draw(st.floats(0.01, 1.0))},
           "pulleys": pulleys, "mesh": {"elements_per_span": draw(st.integers(1, 24))},
           "model": {"gravity": [0.0, draw(st.sampled_from([0.0, -9.81]))]}, "modal": {"modes": 4}}
    if draw(st.booleans()):  # per-span models ([spans]): the fidelity ladder, spring to ANCF, any mix
        spans = {}
        for i in range(n):
            model = draw(st.sampled_from([None, "ancf", "string", "spring"]))
            entry = {} if model is None else {"model": model}
            if model != "spring" and draw(st.booleans()):
                entry["elements"] = draw(st.integers(1, 12))
            if entry:
                spans[f"P{i}-P{(i + 1) % n}"] = entry
        if spans:
            raw["spans"] = spans
    path_length = _path_length(centres, [p["radius"] for p in pulleys])
    if movable and draw(st.booleans()):
        pulleys[movable[0]]["adjustable"] = True
        raw["belt"]["length"] = path_length * draw(st.floats(0.97, 1.0))
        raw["tension"] = {"target": draw(st.floats(0.5, 5e3)), "mode": "adjust"}
    else:
        raw["belt"]["length"] = path_length * draw(st.floats(0.97, 0.9999))
    return raw


def _path_length(centres: np.ndarray, radii: list[float]) -> float:
    """The belt path around convex inside pulleys: the hull's perimeter plus one turn of the radii
    (exact for equal radii, close otherwise; the L0 fit or the stretch takes up the difference)."""
    n = len(radii)
    return float(sum(np.linalg.norm(centres[(i + 1) % n] - centres[i]) for i in range(n))
                 + 2 * math.pi * float(np.mean(radii)))


def _run(tmp_path: Path, raw: dict, command: str = "modal") -> tuple[subprocess.CompletedProcess, Path]:
    cfg, out = tmp_path / "drive.toml", tmp_path / "out.h5"
    for p in (cfg, out):
        if p.exists():
            p.unlink()
    cfg.write_bytes(tomli_w.dumps(raw).encode())
    proc = subprocess.run([sys.executable, "-m", "beltdyn.cli", command, str(cfg), "-o", str(out), "--force"],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    return proc, out


def _no_nan_in_complete_groups(out: Path) -> None:
    if not out.exists():
        return
    with h5py.File(out, "r") as f:
        for name, g in f.items():
            if not isinstance(g, h5py.Group) or g.attrs.get("status") != "complete":
                continue
            for key, ds in g.items():
                if isinstance(ds, h5py.Dataset) and ds.dtype.kind == "f":
                    data = ds[()]
                    allowed_nan = key in ("arm_angle", "arm_torque", "arm_free_angle", "pivot_reaction",
                                          "required_friction", "slip_margin")  # NaN: "no arm / no friction"
                    assert allowed_nan or np.all(np.isfinite(data)), f"/{name}/{key} holds NaN/inf"


def _check(proc: subprocess.CompletedProcess, out: Path) -> None:
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode in (0, 1, 2), (proc.returncode, proc.stderr)
    if proc.returncode:
        assert proc.stderr.strip(), "a failure says why"
    _no_nan_in_complete_groups(out)


FAST = settings(max_examples=12, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
SLOW = settings(max_examples=150, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@FAST
@given(raw=drives())
def test_random_valid_drives_solve_or_fail_by_name(tmp_path, raw):
    proc, out = _run(tmp_path, raw)
    _check(proc, out)


@pytest.mark.slow
@SLOW
@given(raw=drives())
def test_random_valid_drives_solve_or_fail_by_name_long(tmp_path, raw):
    proc, out = _run(tmp_path, raw)
    _check(proc, out)


BAD_VALUES = st.sampled_from([-1.0, 0.0, float("nan"), "text", [1.0], {"x": 1}, True, 1e400])


@st.composite
def broken(draw) -> tuple[dict, str]:
    """A valid drive with one value replaced by something invalid for its key: (raw, key path)."""
    raw = draw(drives())
    where = draw(st.sampled_from(["belt.EA", "belt.mass_per_length", "pulleys.radius", "pulleys.mass",
                                  "mesh.elements_per_span", "belt.length", "unknown"]))
    bad = draw(BAD_VALUES)
    if where == "unknown":
        raw["belt"]["stifness"] = 1.0
        return raw, "belt.stifness"
    if where.startswith("pulleys."):
        i = draw(st.integers(0, len(raw["pulleys"]) - 1))
        raw["pulleys"][i][where.split(".")[1]] = bad
        return raw, f"pulleys[{i}].{where.split('.')[1]}"
    table, key = where.split(".")
    raw[table][key] = bad
    return raw, where


@FAST
@given(case=broken())
def test_random_invalid_drives_exit_2_naming_the_key(tmp_path, case):
    raw, key = case
    try:
        tomli_w.dumps(raw)
    except (TypeError, ValueError):  # not representable in TOML (nan is, 1e400 = inf is): nothing to test
        return
    proc, out = _run(tmp_path, raw, "geometry")
    assert "Traceback" not in proc.stderr, proc.stderr
    if proc.returncode == 0:  # a value that happens to be valid for the key (e.g. 1.0 where a float goes)
        return
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert key.split(".")[-1].split("[")[0] in proc.stderr or key in proc.stderr, (key, proc.stderr)
    assert not out.exists()
