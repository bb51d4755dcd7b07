"""`beltdyn fit`: identification from synthetic measurements made by beltdyn itself with known
parameters (recovered to the noise level; standard deviations against the scatter of repeated noisy
fits), identifiability, the measured file's errors, the command, and the paper's Table 1."""

from __future__ import annotations

import subprocess
import tomllib
from pathlib import Path

import numpy as np
import pytest
from processes import BELTDYN  # tests/processes.py

from beltdyn.config import load_config, with_overrides
from beltdyn.errors import ConfigError
from beltdyn.pipeline import analyse
from beltdyn.results.io import read_group
from beltdyn.study.fit import fit, fitted_config, parse_parameter
from beltdyn.study.measured import read_measured

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs/paper/bench_T200.toml"
TENSIONER = ROOT / "configs/examples/three_pulley_tensioner.toml"
BENCH_TRUTH = {"belt.EA": 1.05e5, "belt.EI": 0.035, "pulleys[0].bearing_stiffness": 2.7e6}
SHOWN = {"transverse": 6, "rotational": 1, "translational": 1}  # the bench's rows: kinds and highest order


def bench_rows(truth: dict, tensions=(200.0, 400.0)) -> list[tuple[float, str, int, float]]:
    """(frequency, kind, order, tension) of the bench at `truth`, by beltdyn: each transverse order as
    the mean of its upper/lower span pair (how a row without a span pairs), the rotational and the
    translational mode."""
    cfg = load_config(BENCH)
    rows = []
    for T in tensions:
        modal = analyse(with_overrides(cfg, [f"tension.target={T}"] + [f"{k}={v!r}" for k, v in truth.items()]),
                        modal=True, n_modes=16).modal
        for kind, top in SHOWN.items():
            for order in range(1, top + 1):
                f = modal.frequency[[k == kind and o == order for k, o in zip(modal.kind, modal.order)]]
                assert len(f) in (1, 2) and f.max() - f.min() < 1e-3 * f.min()  # a pair within 0.1 %
                rows.append((float(f.mean()), kind, order, T))
    return rows


def write_csv(path: Path, rows, noise=None, header="frequency,kind,order,tension.target") -> Path:
    """rows as a measured CSV, each frequency times (1 + noise[i]) if given."""
    lines = [header]
    for i, (f, kind, order, T) in enumerate(rows):
        f = float(f * (1.0 + (noise[i] if noise is not None else 0.0)))
        lines.append(f"{f!r},{kind},{order},{T!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


def bench_fit(csv: Path, keys=tuple(BENCH_TRUTH)):
    cfg = load_config(BENCH)
    return fit(cfg, read_measured(csv), [parse_parameter(cfg, k) for k in keys])


@pytest.fixture(scope="module")
def truth_rows():
    return bench_rows(BENCH_TRUTH)


def test_noise_free_bench_data_recover_EA_EI_and_the_bearing_stiffness(tmp_path, truth_rows):
    # 16 rows in 2 load cases (200 and 400 N) made by beltdyn at EA = 1.05e5 N, EI = 0.035 N m^2,
    # k_t1 = 2.7e6 N/m; the fit starts from the paper's values (1.2e5, 0.02, 2.4253e6) and must return
    # the known values to 1e-6 (the optimizer's tolerance), with the frequencies reproduced.
    res = bench_fit(write_csv(tmp_path / "m.csv", truth_rows))
    assert len(res.measured) == 16 and res.cases == ("tension.target=200.0", "tension.target=400.0")
    np.testing.assert_allclose(res.fitted, list(BENCH_TRUTH.values()), rtol=1e-6)
    assert res.rms_before > 1e-3 and res.rms_after < 1e-8
    assert res.identifiable.all() and res.method == ("analyses", "modal", "modal")
    assert res.mode_label[0] == "1st transverse, spans 1+2 (mean)"
    assert not res.warnings


def test_noisy_bench_data_recovered_within_their_standard_deviations(tmp_path, truth_rows):
    # 0.2 % relative noise (fixed seed): each parameter within 3.5 of its reported standard deviations
    # of the known value, and s^2 the order of the noise variance.
    rng = np.random.default_rng(2811)
    sigma = 2e-3
    res = bench_fit(write_csv(tmp_path / "m.csv", truth_rows, noise=sigma * rng.standard_normal(16)))
    err = (res.fitted - np.array(list(BENCH_TRUTH.values()))) / res.std
    assert np.all(np.abs(err) < 3.5), (res.fitted, res.std)
    assert 0.2 * sigma ** 2 < res.residual_variance < 5 * sigma ** 2
    assert np.allclose(np.diag(res.correlation), 1.0) and np.all(np.abs(res.correlation) <= 1 + 1e-12)


@pytest.mark.slow
def test_standard_deviations_match_the_scatter_of_repeated_noisy_fits(tmp_path, truth_rows):
    # Monte Carlo: 40 fits to the same truth with independent 0.2 % noise; the sample standard deviation
    # of the fitted values against the mean reported one (linearized s^2 (J^T J)^-1): within 30 % (the
    # sampling error of a standard deviation from 40 draws is ~11 %).
    rng = np.random.default_rng(7)
    sigma = 2e-3
    fitted, reported = [], []
    for i in range(40):
        res = bench_fit(write_csv(tmp_path / f"m{i}.csv", truth_rows, noise=sigma * rng.standard_normal(16)))
        fitted.append(res.fitted)
        reported.append(res.std)
    ratio = np.std(fitted, axis=0, ddof=1) / np.mean(reported, axis=0)
    assert np.all(np.abs(ratio - 1.0) < 0.3), ratio


def test_tensioner_spring_and_EI_recovered_on_the_tensioner_drive(tmp_path):
    # The three-pulley drive with a tensioner arm: its lowest eight modes (each row with kind, order
    # and span) made by beltdyn at arm stiffness 52 N m/rad and EI = 0.05 N m^2; the fit from 40 and
    # 0.02 returns both to 1e-6.
    cfg = load_config(TENSIONER)
    truth = {"pulleys.T.arm_stiffness": 52.0, "belt.EI": 0.05}
    modal = analyse(with_overrides(cfg, [f"{k}={v!r}" for k, v in truth.items()]), modal=True).modal
    lines = ["frequency,kind,order,span"]
    for f, k, o, s in list(zip(modal.frequency, modal.kind, modal.order, modal.span))[:8]:
        lines.append(f"{float(f)!r},{k},{o},{s if s else ''}")
    (tmp_path / "m.csv").write_text("\n".join(lines) + "\n")
    assert "tensioner" in modal.kind[:8]
    res = fit(cfg, read_measured(tmp_path / "m.csv"), [parse_parameter(cfg, k) for k in truth])
    np.testing.assert_allclose(res.fitted, list(truth.values()), rtol=1e-6)
    assert res.method == ("modal", "modal")


def test_a_parameter_no_measured_mode_depends_on_is_not_identifiable(tmp_path, truth_rows):
    # Pulley C has a fixed centre: its mass is in no DOF, so no frequency depends on it. It is named,
    # held at its value, and EI is still fitted (to the 16 rows made at EI = 0.035 with EA and k_t1
    # at their true values: EI's recovered to 1e-6).
    truth = {**BENCH_TRUTH}
    cfg = with_overrides(load_config(BENCH), ["belt.EA=105000.0", "pulleys[0].bearing_stiffness=2700000.0"])
    res = fit(cfg, read_measured(write_csv(tmp_path / "m.csv", truth_rows)),
              [parse_parameter(cfg, "belt.EI"), parse_parameter(cfg, "pulleys.C.mass")])
    assert res.identifiable.tolist() == [True, False]
    assert res.fitted[1] == res.initial[1] and np.isnan(res.std[1])
    assert res.fitted[0] == pytest.approx(truth["belt.EI"], rel=1e-6)
    assert any("pulleys.C.mass is not identifiable" in w for w in res.warnings)
    with pytest.raises(ConfigError, match="no parameter can be identified"):
        fit(cfg, read_measured(tmp_path / "m.csv"), [parse_parameter(cfg, "pulleys.C.mass")])


def test_two_parameters_the_data_cannot_separate(tmp_path):
    # Only the first transverse pair at one tension: EI and the mass per length both move it, and one
    # frequency cannot tell them apart; one of them is named not identifiable, the other fitted.
    (tmp_path / "m.csv").write_text("frequency,kind,order\n30.4,transverse,1\n")
    cfg = load_config(BENCH)
    res = fit(cfg, read_measured(tmp_path / "m.csv"),
              [parse_parameter(cfg, "belt.EI"), parse_parameter(cfg, "belt.mass_per_length")])
    assert res.identifiable.sum() == 1
    assert any("cannot separate belt.EI, belt.mass_per_length" in w for w in res.warnings)


def test_unclassified_rows_pair_one_to_one_and_an_ambiguous_one_is_a_warning(tmp_path):
    # Rows without kind pair with the nearest computed mode, one to one (30.6 and 61.0 with the first
    # two transverse pairs, 178 with the translational mode); 96.5 Hz with a 5 Hz scatter lies within
    # reach of the 3rd transverse pair (92.3) and the rotational mode (100.7): paired, and warned.
    (tmp_path / "m.csv").write_text("frequency,scatter\n30.6,\n61.0,\n178.0,\n96.5,5\n")
    cfg = load_config(BENCH)
    res = fit(cfg, read_measured(tmp_path / "m.csv"), [parse_parameter(cfg, "belt.EI")])
    assert res.mode_label[:3] == ("1st transverse, spans 1+2 (mean)", "2nd transverse, spans 1+2 (mean)",
                                  "1st translational")
    assert res.mode_label[3] in ("3rd transverse, spans 1+2 (mean)", "1st rotational")
    assert any("row 5" in w and "ambiguous" in w for w in res.warnings)


def beltdyn(*args, cwd):
    return subprocess.run([*BELTDYN, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=120, check=False)


@pytest.mark.parametrize("text, where, what", [
    ("kind,order\ntransverse,1\n", "row 1, column 'frequency'", "no 'frequency' column"),
    ("frequency,kind\n30.3,transverse\n-61.1,transverse\n", "row 3, column 'frequency'", "must be > 0 Hz"),
    ("frequency,tension.targt\n30.3,200\n", "row 2, column 'tension.targt'", "targt"),
    ("frequency,kind,order\n30.3,transverse,1\n100.0,tensioner,1\n", "row 3, column 'kind'", "no computed mode"),
    ("frequency,kind\n30.3,sideways\n", "row 2, column 'kind'", "unknown kind"),
    ("frequency,kind,order\n30.3,transverse,1.5\n", "row 2, column 'order'", "integer"),
    ("# a comment\nfrequency,wieght\n30.3,1\n", "row 2, column 'wieght'", "unknown column"),
])
def test_bad_measured_files_exit_2_naming_file_row_and_column(tmp_path, text, where, what):
    # Each defect: exit 2, one line naming the measured file, the row (its line in the file) and the
    # column; no traceback, no results file.
    csv = tmp_path / "bad.csv"
    csv.write_text(text)
    r = beltdyn("fit", BENCH, "--measured", csv, "--param", "belt.EI", "-o", tmp_path / "f.h5", cwd=tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    assert str(csv) in r.stderr and where in r.stderr and what in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "f.h5").exists()


def test_fit_command_on_table1_writes_fit_group_and_the_fitted_config(tmp_path):
    # The paper's Table 1 experimental column (12 transverse modes at 200 and 400 N): fitting EI and
    # the mass per length lowers the RMS relative error from 1.03 % (the paper's values) to 0.25 %;
    # /fit holds what the console printed, and --write-config a configuration that reproduces the
    # fitted frequencies.
    out = tmp_path / "fit.h5"
    r = beltdyn("fit", BENCH, "--measured", ROOT / "configs/paper/table1_measured.csv", "--param", "belt.EI",
                "--param", "belt.mass_per_length=0.05:0.5", "-o", out, "--write-config", tmp_path / "fitted.toml",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    g = read_group(out, "fit")
    assert g["attrs"]["status"] == "complete"
    v = g["variables"]
    assert list(g["coords"]["parameter"]) == ["belt.EI", "belt.mass_per_length"]
    assert g["attrs"]["rms_relative_error_before"] == pytest.approx(0.01028, abs=2e-5)
    assert g["attrs"]["rms_relative_error_after"] < 0.003
    assert 0.03 < v["fitted"][0] < 0.04 and v["standard_deviation"][0] > 0
    assert np.asarray(v["reference_frequency"])[5] == 190.3 and np.asarray(v["measured_frequency"])[5] == 194.9
    assert "RMS relative error: before 1.028%" in r.stdout
    fitted = tomllib.loads((tmp_path / "fitted.toml").read_text())
    assert fitted["belt"]["EI"] == pytest.approx(float(v["fitted"][0]), rel=1e-12)
    cfg = load_config(tmp_path / "fitted.toml")
    modal = analyse(cfg, modal=True).modal
    f6 = modal.frequency[[k == "transverse" and o == 6 for k, o in zip(modal.kind, modal.order)]].mean()
    assert f6 == pytest.approx(float(v["frequency_after"][5]), rel=1e-9)


def test_fitted_config_changes_only_the_identified_parameters(tmp_path, truth_rows):
    cfg = load_config(BENCH)
    res = bench_fit(write_csv(tmp_path / "m.csv", truth_rows))
    new = fitted_config(cfg, res)
    assert new.belt.EA == pytest.approx(BENCH_TRUTH["belt.EA"], rel=1e-6)
    assert new.pulleys[0].bearing_stiffness[0] == pytest.approx(2.7e6, rel=1e-6)
    assert new.belt.mass_per_length == cfg.belt.mass_per_length and new.pulleys[1] == cfg.pulleys[1]


def test_bad_param_specs_are_config_errors():
    cfg = load_config(BENCH)
    with pytest.raises(ConfigError, match="not a number"):
        parse_parameter(cfg, "belt.colour")
    with pytest.raises(ConfigError, match="outside"):
        parse_parameter(cfg, "belt.EI=0.1:1")
    with pytest.raises(ConfigError, match="LOW:HIGH"):
        parse_parameter(cfg, "belt.EI=0.1")
    p = parse_parameter(cfg, "belt.EI=0.01:0.1")
    assert p.log and p.scaled_bounds() == pytest.approx((np.log(0.5), np.log(5.0)))


def _artist(fig, gid: str):
    found = [a for ax in fig.axes for a in ax.get_children() if a.get_gid() == gid]
    assert found, gid
    return found[0]


def test_fit_figure_draws_the_fit_group(tmp_path):
    # `beltdyn plot FIT.h5 fit`: measured against computed before and after: the points are /fit's
    # datasets, unchanged.
    pytest.importorskip("matplotlib")
    from beltdyn import plot as P
    from beltdyn.config import config_hash, resolved_toml
    from beltdyn.results.fit import fit_group
    from beltdyn.results.io import write_groups

    cfg = load_config(BENCH)
    res = fit(cfg, read_measured(ROOT / "configs/paper/table1_measured.csv"), [parse_parameter(cfg, "belt.EI")])
    out = tmp_path / "fit.h5"
    write_groups(out, [fit_group(res)], config_toml=resolved_toml(cfg), config_sha256=config_hash(cfg), force=True)
    data = P.read_results(out)
    assert P.available(data) == ("fit",)
    fig = P.figure("fit", data)
    x, y = _artist(fig, "after").get_data()
    np.testing.assert_array_equal(x, res.measured)
    np.testing.assert_array_equal(y, res.after)
    np.testing.assert_array_equal(_artist(fig, "before").get_data()[1], res.before)
    r = beltdyn("plot", out, "-o", tmp_path / "figs", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "figs_fit.png").stat().st_size > 0


def test_measured_points_over_the_sweep_figure(tmp_path):
    # `beltdyn plot SWEEP.h5 sweep --measured CSV`: the Table 1 rows drawn at their tension (200 and
    # 400 N, from the rows' tension.target column) and measured frequency; a row without the swept
    # key is drawn at the sweep configuration's value (200 N).
    pytest.importorskip("matplotlib")
    from beltdyn import plot as P

    sweep = tmp_path / "sweep.h5"
    r = beltdyn("sweep", BENCH, "--param", "tension.target=100:400:3", "--modes", "4", "--workers", "1",
                "--set", "mesh.elements_per_span=4", "-o", sweep, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    fig = P.figure("sweep", P.read_results(sweep), measured=ROOT / "configs/paper/table1_measured.csv")
    x, y = _artist(fig, "measured").get_data()
    np.testing.assert_array_equal(x, [200.0] * 6 + [400.0] * 6)
    np.testing.assert_array_equal(y, read_measured(ROOT / "configs/paper/table1_measured.csv").frequency)
    (tmp_path / "m.csv").write_text("frequency\n30.3\n")
    x, _ = _artist(P.figure("sweep", P.read_results(sweep), measured=tmp_path / "m.csv"), "measured").get_data()
    assert x.tolist() == [200.0]
    r = beltdyn("plot", sweep, "sweep", "--measured", ROOT / "configs/paper/table1_measured.csv", "-o",
                tmp_path / "s.png", cwd=tmp_path)
    assert r.returncode == 0 and (tmp_path / "s.png").stat().st_size > 0, r.stderr
