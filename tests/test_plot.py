"""beltdyn plot: every figure renders headless from result files made by the real commands, and the
plotted data are the file's data (read back from the figure's artists); the belt and the mode shapes
go through the elements' cubic shape functions (checked against a cubic they must reproduce); no two
curves of a panel look alike and no two texts of a figure overlap (from the rendered extents), for
every figure of the examples; bad files exit 2 naming what is missing and the command, with the
file's path, that makes it; -o fig.png names fig_layout.png, ...; the other commands never import
matplotlib."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

pytest.importorskip("matplotlib")

import beltdyn.plot.drive  # noqa: E402,F401
import beltdyn.plot.modes  # noqa: E402,F401
import beltdyn.plot.series  # noqa: E402,F401
import beltdyn.plot.style  # noqa: E402,F401
from beltdyn import plot as P  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
SMALL = ROOT / "configs" / "examples" / "bench_transient_small.toml"
EXAMPLES = ROOT / "configs" / "examples"
EVERY = P.drive.POINTS_PER_ELEMENT  # the nodes are every EVERY-th point of a drawn span


@pytest.fixture(autouse=True)
def _close_figures():
    """Each test's figures closed after it (pyplot keeps every open figure)."""
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


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


def test_layout_draws_the_belt_through_its_nodes_and_the_hub_loads(files):
    res = P.read_results(files["modal"])
    fig = P.figure("layout", res)
    lines = _lines(fig)
    nodes, span = res.var("static", "node_position"), res.var("static", "node_span")
    for s in np.unique(span):
        xy = lines[f"belt span {s}"].get_xydata()
        np.testing.assert_array_equal(xy[::EVERY], nodes[span == s])
        assert len(xy) == EVERY * (np.count_nonzero(span == s) - 1) + 1
    quiver = next(c for ax in fig.axes for c in ax.collections if c.get_gid() == "hub load")
    np.testing.assert_array_equal(np.column_stack([quiver.U, quiver.V]), res.var("static", "hub_load"))
    # the wraps: each arc from the arriving span's end tangent point to the leaving span's start one,
    # on the pulley's circle, through its wrap angle (arc length R x wrap)
    a, b = P.drive.tangent_points(res)
    centre, radius = res.var("static", "pulley_center"), res.var("geometry", "pulley_radius")
    wrap = res.var("static", "wrap_angle")
    for j, name in enumerate(P.drive.pulley_names(res)):
        arc = lines[f"wrap {name}"].get_xydata()
        np.testing.assert_allclose(np.hypot(*(arc - centre[j]).T), radius[j], rtol=1e-12)
        np.testing.assert_allclose(arc[0], b[j - 1], atol=1e-9 * radius[j])
        np.testing.assert_allclose(arc[-1], a[j], atol=1e-6 * radius[j])
        np.testing.assert_allclose(np.hypot(*np.diff(arc, axis=0).T).sum(), radius[j] * wrap[j], rtol=1e-3)
    # a file with /geometry alone: the spans are its tangent lines, and there are no hub loads
    geo = P.read_results(files["geometry"])
    fig = P.figure("layout", geo)
    lines = _lines(fig)
    a, b = geo.var("geometry", "span_start"), geo.var("geometry", "span_end")
    for s in range(len(a)):
        np.testing.assert_array_equal(lines[f"belt span {s}"].get_xydata(), np.vstack([a[s], b[s]]))
    assert not [c for ax in fig.axes for c in ax.collections if c.get_gid() == "hub load"]


def test_hermite_curves_reproduce_a_cubic_exactly():
    # closed form: a planar cubic r(x) = c0 + c1 x + c2 x^2 + c3 x^3 over two elements of length 0.3
    # is in the span of the ANCF cubic shape functions, so nodal r and r' give it back everywhere.
    c = np.array([[0.1, -0.2], [1.0, 0.3], [-0.7, 0.9], [0.4, -1.1]])
    x_nodes = np.array([0.0, 0.3, 0.6])
    r = np.polynomial.polynomial.polyval(x_nodes, c).T
    dr = np.polynomial.polynomial.polyval(x_nodes, np.polynomial.polynomial.polyder(c)).T
    curve = P.hermite_curves(r, dr, np.zeros(3, dtype=int), np.array([0.3]), points=8)[0]
    x = np.r_[np.arange(16) / 8 * 0.3, 0.6]
    np.testing.assert_allclose(curve, np.polynomial.polynomial.polyval(x, c).T, atol=1e-14)


def test_modes_are_the_static_belt_plus_a_scaled_transverse_shape(files):
    res = P.read_results(files["modal"])
    fig = P.figure("modes", res, modes=(1, 2, 7))
    lines = _lines(fig)
    nodes, span = res.var("static", "node_position"), res.var("static", "node_span")
    shape = res.var("modal", "node_shape")
    kinds = [str(k) for k in res.var("modal", "kind")]
    for m in (1, 2, 7):
        drawn, ref = [], []
        for s in np.unique(span):
            seg = nodes[span == s]
            chord = seg[-1] - seg[0]
            n = np.array([-chord[1], chord[0]]) / np.hypot(*chord)
            d = shape[m - 1][span == s]
            drawn.append(lines[f"mode {m} span {s}"].get_xydata()[::EVERY] - seg)
            ref.append((d @ n)[:, None] * n if kinds[m - 1] == "transverse" else d)
        drawn, ref = np.vstack(drawn), np.vstack(ref)
        c = float(np.vdot(drawn, ref) / np.vdot(ref, ref))  # one scale for the whole shape
        np.testing.assert_allclose(drawn, c * ref, atol=1e-12 * max(1.0, np.abs(drawn).max()))
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    freq = res.var("modal", "frequency")
    assert f"{freq[6]:.4g} Hz" in titles[2] and str(res.var("modal", "label")[6]) in titles[2]
    assert " x " in titles[2] and "mm)" in titles[2]  # the drawing scale


def test_equal_lobes_of_a_second_transverse_mode(files):
    # a span's 2nd transverse mode of the bench (a pinned string under tension, nearly sin(2 pi x / L)):
    # its two lobes drawn equal within 2 %
    res = P.read_results(files["modal"])
    label = [str(x) for x in res.var("modal", "label")]
    m = next(i for i, lab in enumerate(label) if lab.startswith("2nd transverse, span 2"))
    normals = P.modes.span_normals(res)
    w, what = P.modes.drawn_motion(P.modes.mode_motion(res, m), normals)
    assert what == "transverse motion"
    s = int(res.var("modal", "span")[m]) - 1
    v = w[s] @ normals[s]
    half = len(v) // 2
    lobes = np.abs(v[:half]).max(), np.abs(v[half:]).max()
    assert abs(lobes[0] - lobes[1]) <= 0.02 * max(lobes), lobes


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
    cx, cf = P.crossings(x, np.full((11, 1), 50.0), (2.0,), 1.0 / (2 * np.pi))
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
    p = _cli("plot", files["modal"], "-o", tmp_path / "fig.png", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "fig_layout.png").stat().st_size > 10_000
    assert (tmp_path / "fig_modes.png").stat().st_size > 10_000
    assert not list(tmp_path.glob("fig.png*"))
    p = _cli("plot", files["modal"], "modes", "--modes", "1-3", "-o", tmp_path / "m.svg", cwd=tmp_path)
    assert p.returncode == 0 and (tmp_path / "m.svg").read_text().startswith("<?xml")


def test_figure_paths():
    r = Path("runs/drive.h5")
    assert P.figure_paths(r, ("layout", "modes"), output=Path("out/fig.png"), single=False) == \
        {"layout": Path("out/fig_layout.png"), "modes": Path("out/fig_modes.png")}
    assert P.figure_paths(r, ("layout",), output=Path("out/fig.svg"), single=False) == {"layout": Path("out/fig_layout.svg")}
    assert P.figure_paths(r, ("layout",), output=Path("out/fig"), single=False) == {"layout": Path("out/fig_layout.png")}
    assert P.figure_paths(r, ("modes",), output=None, single=False) == {"modes": Path("runs/drive_modes.png")}
    assert P.figure_paths(r, ("modes",), output=Path("a/b.pdf"), single=True) == {"modes": Path("a/b.pdf")}


@pytest.mark.parametrize("what, needs", [("modes", "beltdyn modal"), ("sweep", "beltdyn sweep"),
                                         ("transient", "beltdyn transient"), ("response", "beltdyn response")])
def test_a_missing_group_exits_2_naming_the_command(files, tmp_path, what, needs):
    p = _cli("plot", files["geometry"], what, "-o", tmp_path / "x.png", cwd=tmp_path)
    assert p.returncode == 2 and needs in p.stderr and "Traceback" not in p.stderr
    assert f"CONFIG -o {files['geometry']}" in p.stderr.replace("\n", "")  # the file's own path, directory kept
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


# ------------------------------------------------------------------ every figure: looks and texts
def _check_figure(fig, where: str) -> None:
    assert P.alike_curves(fig) == [], where
    assert P.overlapping_texts(fig) == [], where


@pytest.mark.parametrize("name", ["modal", "geometry", "sweep", "transient", "response"])
def test_no_two_curves_alike_and_no_text_overlapping(files, name):
    res = P.read_results(files[name])
    assert P.available(res)
    for kind in P.available(res):
        _check_figure(P.figure(kind, res), f"{name}: {kind}")


EXAMPLE_RUNS = {  # the other examples, each figure of them checked the same way
    "fead_static": ["static", EXAMPLES / "fead_4cyl.toml", "--set", "mesh.elements_per_span=4"],
    "fead_transient": ["transient", EXAMPLES / "fead_4cyl.toml", "--duration", "0.04", "--set",
                       "transient.spectrum.start=0.0", "--set", "mesh.elements_per_span=4"],
    "tensioner": ["modal", EXAMPLES / "three_pulley_tensioner.toml"],
    "backside": ["modal", EXAMPLES / "three_pulley_backside_idler.toml"],
    "campbell": ["sweep", EXAMPLES / "bench_campbell.toml", "--set", 'sweep.params={"running.driver_speed"="0:600:7"}',
                 "--workers", "1", "--set", "mesh.elements_per_span=4"],
    "working_curve": ["sweep", EXAMPLES / "fead_4cyl.toml", "--param", "static.torque[0].value=-12:0:3", "--analysis",
                      "static", "--workers", "1", "--set", "mesh.elements_per_span=4"],
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(EXAMPLE_RUNS))
def test_every_example_figure_has_distinct_curves_and_no_overlapping_text(name, tmp_path):
    out = tmp_path / f"{name}.h5"
    p = _cli(*EXAMPLE_RUNS[name], "-o", out, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    res = P.read_results(out)
    assert P.available(res)
    for kind in P.available(res):
        fig = P.figure(kind, res)
        _check_figure(fig, f"{name}: {kind}")
        if kind == "transient":  # torque-free pulleys' margins (~1e12 or inf) are not drawn
            for line in (ln for ax in fig.axes for ln in ax.get_lines() if (ln.get_gid() or "").startswith("slip_margin")):
                assert np.nanmax(np.abs(line.get_ydata())) < 1e6


def test_the_checks_can_fail():
    plt = P.style.pyplot()
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1], color=P.OKABE_ITO[0], label="a")
    ax.plot([0, 1], [1, 0], color=P.OKABE_ITO[0], label="b")  # the same look as "a"
    ax.plot([0, 1], [0.5, 0.5], color=P.OKABE_ITO[0], label="_a")  # a piece of "a": may look like it
    ax.text(0.5, 0.5, "one label")
    ax.text(0.5, 0.5, "another label")
    assert P.alike_curves(fig) == [("a", "b")]
    assert ("one label", "another label") in P.overlapping_texts(fig)
    plt.close(fig)


def test_curve_styles_are_distinct_for_many_curves():
    looks = {(st["color"], st["linestyle"], st["marker"]) for st in map(P.style.curve_style, range(56))}
    assert len(looks) == 56


def test_slip_margin_panels_leave_out_torque_free_pulleys():
    y = np.column_stack([np.full(5, 1.7), np.full(5, np.inf), np.full(5, 6.5e12), np.full(5, np.nan)])
    assert P.series.shown_channels("slip_margin", y) == [0]
    assert P.series.shown_channels("span_tension", y[:, :3]) == [0, 2]  # (no finite sample: nothing to draw)


def test_sweep_corner_names_the_sweep_and_labels_read(files):
    res = P.read_results(files["sweep"])
    fig = P.figure("sweep", res)
    tag = fig.get_suptitle()
    assert "tension.target 100 to 300 N (3 cases)" in tag and "base case" in tag
    res = P.read_results(files["transient"])
    fig = P.figure("transient", res)
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert all("_" not in lab for lab in labels), labels
    peaks = [t.get_text() for ax in fig.axes for t in ax.texts if (t.get_gid() or "").startswith("peak ")]
    assert len(peaks) == len(set(peaks))


def test_campbell_labels_every_order():
    # a synthetic Campbell sweep (three orders): each order line has its label
    import types

    g = {"variables": {"param_running_driver_speed": np.linspace(0, 600, 7), "frequency": np.tile([[30.0, 60.0]], (7, 1)),
                       "label": ["a", "b"]},
         "coords": {}, "dims": {}, "units": {"param_running_driver_speed": "rad/s"},
         "attrs": {"params": '[{"key": "running.driver_speed"}]', "status": "complete"}}
    res = P.Results(path=Path("x.h5"), groups=types.MappingProxyType({"sweep": g}),
                    config=types.MappingProxyType({"running": {"orders": [1.0, 2.0, 4.0]}}), config_text="",
                    attrs=types.MappingProxyType({}))
    fig = P.figure("sweep", res)
    texts = {t.get_text() for ax in fig.axes for t in ax.texts}
    assert {"order 1", "order 2", "order 4"} <= texts
    _check_figure(fig, "synthetic Campbell")
