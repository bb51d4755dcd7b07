"""beltdyn plot: every figure renders headless from result files made by the real commands, and the
plotted data are the file's data (read back from the figure's artists); bad files exit 2 naming what
is missing and the command that makes it; the other commands never import matplotlib."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

pytest.importorskip("matplotlib")

from beltdyn import plot as P  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
SMALL = ROOT / "configs" / "examples" / "bench_transient_small.toml"


def _cli(*args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "beltdyn.cli", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("plot")
    out = {}
    out["modal"] = d / "modal.h5"
    assert _cli("modal", BENCH, "--set", "mesh.elements_per_span=6", "-o", out["modal"], cwd=d).returncode == 0
    out["geometry"] = d / "geometry.h5"
    assert _cli("geometry", BENCH, "-o", out["geometry"], cwd=d).returncode == 0
    out["sweep"] = d / "sweep.h5"
    assert _cli("sweep", BENCH, "--param", "tension.target=100:300:3", "--modes", "4", "--workers", "1",
                "--set", "mesh.elements_per_span=4", "-o", out["sweep"], cwd=d).returncode == 0
    out["transient"] = d / "transient.h5"
    p = _cli("transient", SMALL, "--duration", "0.05", "--set", "transient.spectrum.start=0.0", "-o", out["transient"],
             cwd=d)
    assert p.returncode == 0, p.stderr
    raw = tomllib.loads(BENCH.read_text())
    raw["mesh"]["elements_per_span"] = 4
    raw["response"] = {"speed": [50.0, 400.0], "points": 12, "orders": [1.0, 2.0], "damping": {"rayleigh_mass": 5.0},
                       "excitation": [{"pulley": "A", "kind": "speed", "amplitude": 1.0}]}
    cfg = d / "resp.toml"
    cfg.write_bytes(tomli_w.dumps(raw).encode())
    out["response"] = d / "response.h5"
    assert _cli("response", cfg, "-o", out["response"], cwd=d).returncode == 0
    return out


def _lines(fig) -> dict:
    return {ln.get_gid(): ln for ax in fig.axes for ln in ax.get_lines() if ln.get_gid()}


def test_layout_draws_the_belt_nodes_and_the_hub_loads(files):
    res = P.read_results(files["modal"])
    fig = P.figure("layout", res)
    lines = _lines(fig)
    nodes, span = res.var("static", "node_position"), res.var("static", "node_span")
    for s in np.unique(span):
        np.testing.assert_array_equal(lines[f"belt span {s}"].get_xydata(), nodes[span == s])
    quiver = next(c for ax in fig.axes for c in ax.collections if c.get_gid() == "hub load")
    np.testing.assert_array_equal(np.column_stack([quiver.U, quiver.V]), res.var("static", "hub_load"))
    # a file with /geometry alone: the spans are its tangent lines, and there are no hub loads
    geo = P.read_results(files["geometry"])
    fig = P.figure("layout", geo)
    lines = _lines(fig)
    a, b = geo.var("geometry", "span_start"), geo.var("geometry", "span_end")
    for s in range(len(a)):
        np.testing.assert_array_equal(lines[f"belt span {s}"].get_xydata(), np.vstack([a[s], b[s]]))
    assert not [c for ax in fig.axes for c in ax.collections if c.get_gid() == "hub load"]


def test_modes_are_the_static_nodes_plus_a_scaled_node_shape(files):
    res = P.read_results(files["modal"])
    fig = P.figure("modes", res, modes=(1, 2, 7))
    lines = _lines(fig)
    nodes, span = res.var("static", "node_position"), res.var("static", "node_span")
    shape = res.var("modal", "node_shape")
    for m in (1, 2, 7):
        for s in np.unique(span):
            d = lines[f"mode {m} span {s}"].get_xydata() - nodes[span == s]
            ref = shape[m - 1][span == s]
            c = float(np.vdot(d, ref) / np.vdot(ref, ref))  # one scale for the whole shape
            np.testing.assert_allclose(d, c * ref, atol=1e-12 * max(1.0, np.abs(d).max()))
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    freq = res.var("modal", "frequency")
    assert f"{freq[6]:.4g} Hz" in titles[2] and str(res.var("modal", "label")[6]) in titles[2]


def test_sweep_lines_are_the_tracked_frequencies(files):
    res = P.read_results(files["sweep"])
    fig = P.figure("sweep", res)
    lines = _lines(fig)
    x = res.var("sweep", "param_tension_target")
    f = res.var("sweep", "frequency")
    for k in range(f.shape[1]):
        np.testing.assert_array_equal(lines[f"mode {k + 1}"].get_xdata(), x)
        np.testing.assert_array_equal(lines[f"mode {k + 1}"].get_ydata(), f[:, k])
    assert "tension.target (N)" == fig.axes[0].get_xlabel()


def test_campbell_crossings_are_where_a_mode_meets_an_order_line():
    # A synthetic frequency map: a mode at constant 50 Hz meets order 2 (f = 2 x / 2 pi) at x = 50 pi.
    x = np.linspace(100.0, 200.0, 11)
    cx, cf = P._crossings(x, np.full((11, 1), 50.0), (2.0,), 1.0 / (2 * np.pi))
    np.testing.assert_allclose(cx, [50.0 * np.pi], rtol=1e-12)
    np.testing.assert_allclose(cf, [50.0], rtol=1e-12)


def test_transient_histories_and_spectrum_are_the_files(files):
    res = P.read_results(files["transient"])
    fig = P.figure("transient", res)
    lines = _lines(fig)
    g = res.groups["transient"]
    T = np.asarray(g["variables"]["span_tension"])
    spans = [str(s) for s in g["coords"]["span"]]
    np.testing.assert_array_equal(lines[f"span_tension {spans[0]} start"].get_ydata(), T[:, 0, 0])
    np.testing.assert_array_equal(lines[f"span_tension {spans[0]} start"].get_xdata(), g["coords"]["time"])
    spec = res.groups["transient/spectrum"]
    key = next(k for k in lines if k.startswith("spectrum "))
    np.testing.assert_array_equal(lines[key].get_xdata(), spec["coords"]["frequency"])


def test_response_lines_are_the_largest_amplitudes(files):
    res = P.read_results(files["response"])
    fig = P.figure("response", res)
    lines = _lines(fig)
    a = res.var("response", "span_tension_amplitude")
    for o, k in enumerate(res.coord("response", "order")):
        np.testing.assert_array_equal(lines[f"span_tension_amplitude order {k:g}"].get_ydata(),
                                      a[:, o].reshape(a.shape[0], -1).max(axis=1))


def test_cli_writes_every_figure_the_file_holds(files, tmp_path):
    p = _cli("plot", files["modal"], "-o", tmp_path / "fig", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "fig_layout.png").stat().st_size > 10_000
    assert (tmp_path / "fig_modes.png").stat().st_size > 10_000
    p = _cli("plot", files["modal"], "modes", "--modes", "1-3", "-o", tmp_path / "m.svg", cwd=tmp_path)
    assert p.returncode == 0 and (tmp_path / "m.svg").read_text().startswith("<?xml")


@pytest.mark.parametrize("what, needs", [("modes", "beltdyn modal"), ("sweep", "beltdyn sweep"),
                                         ("transient", "beltdyn transient"), ("response", "beltdyn response")])
def test_a_missing_group_exits_2_naming_the_command(files, tmp_path, what, needs):
    p = _cli("plot", files["geometry"], what, "-o", tmp_path / "x.png", cwd=tmp_path)
    assert p.returncode == 2 and needs in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "x.png").exists()


def test_missing_and_corrupt_files_exit_2(tmp_path):
    p = _cli("plot", tmp_path / "none.h5", cwd=tmp_path)
    assert p.returncode == 2 and "no such results file" in p.stderr and "Traceback" not in p.stderr
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an hdf5 file at all")
    p = _cli("plot", bad, cwd=tmp_path)
    assert p.returncode == 2 and "Traceback" not in p.stderr


@pytest.mark.parametrize("args", [["--help"], ["geometry", str(BENCH), "-o", "g.h5"]])
def test_other_commands_do_not_import_matplotlib(tmp_path, args):
    code = ("import sys\nfrom beltdyn.cli import app\ntry:\n    app(args=%r)\nexcept SystemExit:\n    pass\n"
            "print('MPL' if any(m.startswith('matplotlib') for m in sys.modules) else 'CLEAN')" % (args,))
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.stdout.strip().endswith("CLEAN"), p.stdout + p.stderr
