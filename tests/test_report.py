"""beltdyn report: the report of each kind of results file (static, modal, sweep, Campbell, transient,
response, made here by the real CLI from the shipped configurations) renders in headless Chromium
without a console error, an uncaught exception or a network request; every figure has a non-zero
rendered size; every table the file's groups call for is there; the numbers in the tables, read back
from the rendered page, equal the file's values (read here with h5py, independently of the report's
code); a screenshot and an A4 PDF are saved. Chromium is driven over the DevTools protocol on a pipe
(tests/browser.py, standard library only)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import h5py
import numpy as np
import pytest

pytest.importorskip("matplotlib")

sys.path.insert(0, str(Path(__file__).resolve().parent))
from browser import Browser, chromium  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
CAMPBELL = ROOT / "configs" / "examples" / "bench_campbell.toml"
SMALL = ROOT / "configs" / "examples" / "bench_transient_small.toml"
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"
TENSIONER = ROOT / "configs" / "examples" / "three_pulley_tensioner.toml"
RAD = 180.0 / np.pi

# kind -> (the CLI arguments that make its results file, the figures and tables its report must hold)
CASES = {
    "modal": (["modal", BENCH, "--set", "mesh.elements_per_span=6"],
              ["figure-layout", "figure-modes"], ["table-pulleys", "table-spans", "table-modes"]),
    "transient": (["transient", SMALL, "--duration", "0.05", "--set", "transient.spectrum.start=0.0"],
                  ["figure-layout", "figure-modes", "figure-transient"],
                  ["table-pulleys", "table-spans", "table-modes", "table-transient", "table-extremes"]),
    "sweep": (["sweep", BENCH, "--param", "tension.target=100:600:3", "--modes", "4", "--workers", "1",
               "--set", "mesh.elements_per_span=4"], ["figure-sweep"], ["table-sweep"]),
    "static": (["static", FEAD, "--set", "mesh.elements_per_span=4"], ["figure-layout"],
               ["table-pulleys", "table-spans", "table-tensioner"]),
    "tensioner": (["modal", TENSIONER], ["figure-layout", "figure-modes"],
                  ["table-pulleys", "table-spans", "table-tensioner", "table-modes"]),
    "campbell": (["sweep", CAMPBELL, "--set", 'sweep.params={"running.driver_speed"="0:600:5"}', "--workers", "1",
                  "--set", "mesh.elements_per_span=4"], ["figure-sweep"], ["table-crossings"]),
    "working_curve": (["sweep", FEAD, "--param", "static.torque[0].value=-12:0:3", "--analysis", "static",
                       "--workers", "1", "--set", "mesh.elements_per_span=4"], ["figure-sweep"], ["table-sweep"]),
    "response": (["response", FEAD, "--set", "response.points=12", "--set", "mesh.elements_per_span=4"],
                 ["figure-layout", "figure-response"], ["table-pulleys", "table-response"]),
}
FAST = ("modal", "transient", "sweep")  # the default run; the others are marked slow (over ~30 s each here)


def _cli(*args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "beltdyn.cli", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=900)


@pytest.fixture(scope="module")
def browser():
    exe = chromium()
    if exe is None:
        pytest.skip("Chromium is not installed (apt-get install chromium; .ci/run installs it)")
    with Browser(exe) as b:
        yield b


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("report")


class Tables(HTMLParser):
    """The page's tables by id: rows of (text, data-value or None) cells, header rows left out."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[tuple[str, float | None]]]] = {}
        self._table = None
        self._row = None
        self._cell = None
        self._svg_depth = 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self._table = self.tables.setdefault(a.get("id", f"table {len(self.tables)}"), [])
        elif tag == "tr" and self._table is not None:
            self._row = []
        elif tag == "td" and self._row is not None:
            self._cell = ["", float(a["data-value"]) if "data-value" in a else None]

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            self._row.append((self._cell[0].strip(), self._cell[1]))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            if self._row:
                self._table.append(self._row)
            self._row = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell[0] += data


def _shown(cell, value, *, rtol=5e-6):
    """A cell shows `value` (6 significant digits) and holds it (data-value, to rounding of the
    conversion to the shown unit)."""
    text, held = cell
    if not np.isfinite(value):
        assert text in ("n/a", "infinite", "-infinite"), (text, value)
        return
    np.testing.assert_allclose(float(text), value, rtol=rtol, atol=1e-300, err_msg=f"cell {text!r}")
    np.testing.assert_allclose(held, value, rtol=1e-12, atol=1e-300)


def _report(kind, workdir, browser):
    """Make the results file and its report with the CLI, open it in Chromium: (h5 path, session,
    tables parsed from the rendered DOM)."""
    args, _, _ = CASES[kind]
    h5 = workdir / f"{kind}.h5"
    p = _cli(*args, "-o", h5, "--force", cwd=workdir)
    assert p.returncode == 0, p.stderr
    html = workdir / f"{kind}.html"
    p = _cli("report", h5, "-o", html, cwd=workdir)
    assert p.returncode == 0 and p.stdout.strip() == f"wrote {html}", p.stdout + p.stderr
    session = browser.open(html.as_uri())
    parser = Tables()
    parser.feed(browser.evaluate(session, "document.documentElement.outerHTML"))
    return h5, html, session, parser.tables


def _check_page(kind, html, session, browser, tables):
    _, figures, wanted = CASES[kind]
    page = browser.page(session)
    assert page.errors == [], page.errors
    assert page.requests == [html.as_uri()], page.requests  # no network, nothing but the file itself
    sizes = browser.evaluate(session, "[...document.querySelectorAll('figure')].map(f => { const r = "
                                      "f.querySelector('svg').getBoundingClientRect(); return [f.id, r.width, r.height]; })")
    assert [s[0] for s in sizes] == figures, sizes
    assert all(w > 100 and h > 100 for _, w, h in sizes), sizes
    assert not browser.evaluate(session, "document.querySelectorAll('script').length")
    assert set(wanted) <= set(tables), sorted(tables)
    assert all(len(tables[t]) > 0 for t in wanted)
    shot, pdf = html.with_suffix(".png"), html.with_suffix(".pdf")
    browser.screenshot(session, shot)
    browser.pdf(session, pdf)
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 20_000
    assert pdf.read_bytes()[:5] == b"%PDF-" and pdf.stat().st_size > 20_000


def _var(f, path):
    v = f[path][()]
    return np.array([x.decode() for x in v]) if v.dtype.kind in "SO" else np.asarray(v)


def _check_pulleys_spans(f, tables):
    names = _var(f, "geometry/pulley") if "geometry/pulley" in f else None
    rows = tables["table-pulleys"]
    radius = _var(f, "geometry/pulley_radius")
    st = "static" in f
    wrap = _var(f, ("static" if st else "geometry") + "/wrap_angle")
    for j, row in enumerate(rows):
        if names is not None:
            assert row[0][0] == names[j]
        _shown(row[3], radius[j] * 1e3)
        _shown(row[4], wrap[j] * RAD)
        if st:
            hub = _var(f, "static/hub_load")[j]
            _shown(row[5], float(np.hypot(*hub)))
            _shown(row[6], float(np.arctan2(hub[1], hub[0]) * RAD), rtol=2e-5)
            _shown(row[7], _var(f, "static/applied_torque")[j])
            _shown(row[8], _var(f, "static/required_friction")[j])
            margin = float(_var(f, "static/slip_margin")[j])
            if np.isfinite(margin) and margin < 1e6:
                _shown(row[9], margin)
            elif np.isnan(margin):
                assert row[9][0] == "n/a"
            else:  # a torque-free pulley: ~1e12 or infinite, not a number to show
                assert row[9][0].startswith("not limited") and row[9][1] is None
    if st:
        T = _var(f, "static/span_tension")
        length = _var(f, "static/span_length")
        for s, row in enumerate(tables["table-spans"]):
            _shown(row[1], length[s] * 1e3)
            _shown(row[2], T[s, 0])
            _shown(row[3], T[s, 1])
            assert row[4][0] == _var(f, "static/span_model")[s]
            _shown(row[5], _var(f, "static/span_elements")[s])


def _check_modes(f, tables):
    freq = _var(f, "modal/frequency")
    share = _var(f, "modal/energy_share")
    label = _var(f, "modal/label")
    rows = tables["table-modes"]
    assert len(rows) == len(freq)
    for m, row in enumerate(rows):
        _shown(row[1], freq[m])
        assert row[2][0] == label[m]
        for k in range(share.shape[1]):
            _shown(row[3 + k], share[m, k])
    kind, span = _var(f, "modal/kind"), _var(f, "modal/span")
    for s, row in enumerate(tables["table-spans"]):  # the first transverse frequency of each span
        mine = [freq[m] for m in range(len(freq)) if kind[m] == "transverse" and span[m] == s + 1]
        if mine:
            _shown(row[-1], min(mine))
        else:
            assert row[-1][0] == "n/a"


def _check_tensioner(f, tables):
    angle = _var(f, "static/arm_angle")
    arms = [j for j in range(len(angle)) if np.isfinite(angle[j])]
    rows = tables["table-tensioner"]
    assert len(rows) == len(arms)
    for row, j in zip(rows, arms):
        _shown(row[1], angle[j] * RAD)
        _shown(row[3], _var(f, "static/arm_torque")[j])
        _shown(row[4], float(np.hypot(*_var(f, "static/pivot_reaction")[j])))


@pytest.mark.parametrize("kind", [k if k in FAST else pytest.param(k, marks=pytest.mark.slow) for k in CASES])
def test_report_renders_in_chromium_and_its_tables_are_the_files(kind, workdir, browser):
    h5, html, session, tables = _report(kind, workdir, browser)
    _check_page(kind, html, session, browser, tables)
    with h5py.File(h5, "r") as f:
        if "geometry" in f and "table-pulleys" in CASES[kind][2]:
            _check_pulleys_spans(f, tables)
        if "modal" in f:
            _check_modes(f, tables)
        if "table-tensioner" in CASES[kind][2]:
            _check_tensioner(f, tables)
        if kind == "sweep":
            x, freq = _var(f, "sweep/param_tension_target"), _var(f, "sweep/frequency")
            rows = tables["table-sweep"]
            for i, row in zip(np.argsort(x, kind="stable"), rows):
                _shown(row[0], x[i])
                for k in range(freq.shape[1]):
                    _shown(row[1 + k], freq[i, k])
        if kind == "working_curve":  # the tensioner's arm angle and spring torque against the torque
            x = _var(f, "sweep/param_static_torque_0__value")
            angle, torque = _var(f, "sweep/arm_angle"), _var(f, "sweep/arm_torque")
            arm = int(np.flatnonzero(np.isfinite(angle[0]))[0])
            for i, row in zip(np.argsort(x, kind="stable"), tables["table-sweep"]):
                _shown(row[0], x[i])
                _shown(row[1], angle[i, arm])
                _shown(row[2], torque[i, arm])
        if kind == "campbell":
            cx, cf = _var(f, "sweep/crossing_driver_speed"), _var(f, "sweep/crossing_frequency")
            rows = tables["table-crossings"]
            assert len(rows) == len(cx) > 0
            for i, row in zip(np.argsort(cx, kind="stable"), rows):
                _shown(row[0], _var(f, "sweep/crossing_order")[i])
                _shown(row[2], cx[i])
                _shown(row[3], cf[i])
        if kind == "response":
            speed, orders = _var(f, "response/speed"), _var(f, "response/order")
            T = _var(f, "response/span_tension_amplitude").reshape(len(speed), len(orders), -1).max(axis=2)
            H = np.hypot(*np.moveaxis(_var(f, "response/hub_load_amplitude"), -1, 0))
            H = H.reshape(len(speed), len(orders), -1).max(axis=2)
            for o, row in enumerate(tables["table-response"]):
                _shown(row[0], orders[o])
                _shown(row[1], T[:, o].max())
                _shown(row[2], speed[np.argmax(T[:, o])])
                _shown(row[4], H[:, o].max())
        if kind == "transient":
            t = _var(f, "transient/time")
            T = _var(f, "transient/span_tension").reshape(len(t), -1)
            rows = [r for r in tables["table-extremes"] if r[0][0] == "span tension"]
            assert len(rows) == T.shape[1]
            for c, row in enumerate(rows):
                _shown(row[3], T[:, c].min())
                _shown(row[4], t[np.argmin(T[:, c])])
                _shown(row[5], T[:, c].max())
                _shown(row[6], t[np.argmax(T[:, c])])
            summary = {r[0][0]: r[1] for r in tables["table-transient"]}
            _shown(summary["energy-balance error (1)"], float(f["transient"].attrs["energy_balance_error"]))


def test_the_browser_check_sees_errors_scripts_and_requests(tmp_path, browser):
    # the harness itself can fail: a page with a console error, an uncaught exception and a request
    page = tmp_path / "bad.html"
    page.write_text('<!DOCTYPE html><html><head><link rel="icon" href="data:,"></head><body>'
                    '<img src="http://127.0.0.1:9/none.png"><script>console.error("broken"); '
                    "undefined_function();</script></body></html>")
    session = browser.open(page.as_uri())
    seen = browser.page(session)
    assert any("broken" in e for e in seen.errors) and any("undefined_function" in e for e in seen.errors)
    assert "http://127.0.0.1:9/none.png" in seen.requests


def test_report_of_a_missing_file_exits_2(tmp_path):
    p = _cli("report", tmp_path / "none.h5", cwd=tmp_path)
    assert p.returncode == 2 and "no such results file" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "none.html").exists()


def test_report_is_self_contained_and_printable(workdir, browser):
    html = workdir / "modal.html"
    if not html.exists():
        _report("modal", workdir, browser)
    text = html.read_text()
    assert "<script" not in text
    assert not re.search(r"""(src|href)\s*=\s*["'](https?:)?//""", text)  # nothing to fetch (namespaces are names)
    assert "<metadata>" not in text
    assert "@page { size: A4" in text and "page-break-inside: avoid" in text
    assert json.dumps("resolved configuration (TOML)")[1:-1] in text
