"""Tests of bad input at the command line (the issue's "Bad input" acceptance criteria), `--set`
overrides, the resolved-TOML round trip and config hash, output-file protection, --help/--version.

The broken drive descriptions live in tests/data/bad/: each is a small variation of the smoke
two-pulley config (configs/smoke/two_pulley.toml) whose first line is a comment saying what is
broken. The real CLI runs in a subprocess with cwd=tmp_path; the two runs of one case (fresh output
path / existing results file) run concurrently to keep the file fast.
"""

from __future__ import annotations

import hashlib
import math
import os
import shutil
import subprocess
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import beltdyn
from beltdyn.config import config_from_dict, config_hash, load_config, resolved_toml, with_overrides
from beltdyn.errors import ConfigError
from beltdyn.model.geometry import layout_from_config
from beltdyn.results.io import read_root_attrs
import processes  # tests/processes.py
from processes import BELTDYN  # tests/processes.py

ROOT = Path(__file__).resolve().parents[1]
BAD = Path(__file__).resolve().parent / "data" / "bad"
SMOKE = ROOT / "configs" / "smoke" / "two_pulley.toml"
ALL_CONFIGS = sorted((ROOT / "configs").glob("*/*.toml"))


# file stem -> (key path named in the message (None: a TOML syntax error has no key), fragments the
# message must also contain). Key paths are as the user sees them (a line break shown as "\n").
BAD_CASES: dict[str, tuple[str | None, list[str]]] = {
    "toml_syntax_error": (None, ["TOML syntax error", "at line 24"]),
    "missing_belt": ("belt", ["missing table [belt]"]),
    "missing_belt_EA": ("belt.EA", ["missing key"]),
    "missing_pulley_inertia": ("pulleys[1].inertia", ["missing key"]),
    "wrong_type_string_radius": ("pulleys[0].radius", ["must be a number", "'0.0375'"]),
    "wrong_type_bool_string": ("pulleys[0].adjustable", ["must be true or false", "'true'"]),
    "wrong_type_float_int": ("mesh.elements_per_span", ["must be an integer", "2.5"]),
    "wrong_length_vector": ("pulleys[1].center", ["must be a list of 2 numbers"]),
    "negative_radius": ("pulleys[1].radius", ["must be > 0", "-0.1016"]),
    "zero_mass": ("pulleys[1].mass", ["must be > 0", "got 0"]),
    "negative_EI": ("belt.EI", ["must be >= 0", "-0.02"]),
    "negative_tension": ("tension.target", ["must be > 0", "-200"]),
    "nan_value": ("belt.EA", ["must be finite", "nan"]),
    "inf_value": ("pulleys[1].center[0]", ["must be finite", "inf"]),
    "unknown_key_typo": ("pulleys[1].radiu", ["unknown key 'radiu'", "did you mean 'radius'?"]),
    "unknown_key_with_newline": ("pulleys[1].radius\n", ["unknown key", "did you mean 'radius'?"]),
    "unknown_table_typo": ("tensoin", ["unknown key 'tensoin'", "did you mean 'tension'?"]),
    "bad_support_name": ("pulleys[0].support", ["must be one of", "'slider'"]),
    "bad_curvature_choice": ("model.curvature", ["must be one of", "'quadratic'"]),
    "empty_pulley_list": ("pulleys", ["need at least 2 pulleys, got 0"]),
    "single_pulley": ("pulleys", ["need at least 2 pulleys, got 1"]),
    "duplicate_pulley_names": ("pulleys[1].name", ["duplicate pulley name 'A'"]),
    "two_adjustable": ("pulleys[1].adjustable", ["only one pulley may be adjustable"]),
    "adjustable_without_slide": ("pulleys[0].adjustable", ['needs support = "slide"']),
    "zero_slide_direction": ("pulleys[0].slide_direction", ["must not be the zero vector"]),
    "bad_slide_range": ("pulleys[0].slide_range", ["min < max"]),
    "overlapping_pulleys": ("pulleys[1].center", ["'A' and 'C' overlap"]),
    "L0_too_short": ("belt.length", ["L0 = 0.5 m is too short"]),
    "L0_too_long_for_slide": ("belt.length", ["L0 = 1.9 m is too long to reach along the slide", "slide_range"]),
    "span_cuts_through_pulley": ("pulleys[2].center", ["span A-C cuts through pulley 'B'"]),
}

# Representative cases also run through `static` and `modal` (syntax, value check, unknown key,
# and a failure found only by the geometry stage).
PIPELINE_SUBSET = ["toml_syntax_error", "negative_radius", "unknown_key_typo", "L0_too_long_for_slide"]

# Bad --set on the good smoke config: (command, assignment, key path named, fragments).
BAD_SETS = [
    ("geometry", "tension.target", "--set tension.target", ["expected KEY=VALUE"]),
    ("geometry", "tension.targt=400", "tension.targt", ["unknown key 'targt'", "did you mean 'target'?"]),
    ("geometry", "pulleys[0].radius=abc", "pulleys[0].radius", ["must be a number, got 'abc'"]),
    ("geometry", "pulleys[5].radius=1", "--set pulleys[5].radius=1", ["index 5 out of range (have 2)"]),
    ("geometry", "belt.EA=1.2.3", "--set belt.EA=1.2.3", ["'1.2.3' is not a TOML literal"]),
    ("geometry", "belt.EA=nan", "belt.EA", ["must be finite"]),
    ("static", "pulleys.Z.mass=1", "--set pulleys.Z.mass=1", ["no entry named 'Z'"]),
    ("modal", "frobnicate=1", "--set frobnicate=1", ["unknown key 'frobnicate'"]),
]


# ------------------------------------------------------------------------------------- helpers
_env = processes.plain_env


def run_cli(*calls: tuple[list[str], Path]) -> list[subprocess.CompletedProcess]:
    """Run `beltdyn ARGS` for each (args, cwd) concurrently; results in the same order."""
    procs = [(args, subprocess.Popen([*BELTDYN, *args], cwd=cwd, env=_env(), text=True,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE)) for args, cwd in calls]
    out = []
    for args, p in procs:
        stdout, stderr = p.communicate(timeout=120)
        out.append(subprocess.CompletedProcess([*BELTDYN, *args], p.returncode, stdout, stderr))
    return out


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def shown(key: str) -> str:
    """A key path as the one-line console message shows it."""
    return key.replace("\n", "\\n")


def assert_rejected(proc: subprocess.CompletedProcess, file: str, key: str | None, fragments: list[str]) -> str:
    """Exit 2, no traceback, nothing on stdout, one stderr line `error: FILE: KEY: message`."""
    everything = proc.stdout + proc.stderr
    assert "Traceback" not in everything, everything
    assert proc.returncode == 2, everything
    assert proc.stdout.strip() == "", everything
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    line = lines[0]
    prefix = f"error: {file}: " + (f"{shown(key)}: " if key is not None else "")
    assert line.startswith(prefix), f"{line!r} does not start with {prefix!r}"
    for fragment in fragments:
        assert fragment in line, f"{fragment!r} not in {line!r}"
    return line


def check_rejected_both_ways(tmp_path: Path, good_results: Path, args: list[str], *, file: str, key: str | None,
                             fragments: list[str], force_on_existing: bool = False) -> None:
    """Run `args` twice: with `-o out.h5` (no file there: none may be created, no temp file left) and
    with `-o existing.h5` (a valid results file there: its bytes, inode and mtime must not change)."""
    fresh, old = tmp_path / "fresh", tmp_path / "old"
    fresh.mkdir()
    old.mkdir()
    existing = old / "existing.h5"
    shutil.copy2(good_results, existing)
    before, stat_before = sha256(existing), existing.stat()
    extra = ["--force"] if force_on_existing else []
    r_fresh, r_old = run_cli(([*args, "-o", "out.h5"], fresh), ([*args, "-o", "existing.h5", *extra], old))
    for r in (r_fresh, r_old):
        assert_rejected(r, file, key, fragments)
    assert not (fresh / "out.h5").exists()
    assert sorted(os.listdir(fresh)) == [], "files created by a rejected run"  # no output, no *.tmp*, no results/
    assert sorted(os.listdir(old)) == ["existing.h5"], "files created by a rejected run"
    assert sha256(existing) == before
    stat_after = existing.stat()
    assert (stat_after.st_ino, stat_after.st_mtime_ns) == (stat_before.st_ino, stat_before.st_mtime_ns)


@pytest.fixture(scope="session")
def good_results(tmp_path_factory) -> Path:
    """A valid results file written by a good `geometry` run of the smoke config."""
    d = tmp_path_factory.mktemp("good")
    (r,) = run_cli((["geometry", str(SMOKE), "-o", "good.h5"], d))
    assert r.returncode == 0, r.stdout + r.stderr
    assert read_root_attrs(d / "good.h5")["config_sha256"] == config_hash(load_config(SMOKE))
    return d / "good.h5"


# ---------------------------------------------------------------------------------- bad files
def test_bad_files_are_all_listed_and_documented():
    # Checks: every file in tests/data/bad is a listed case (none silently untested), there are at
    # least 18, and each starts with a comment line saying what is broken.
    files = sorted(p.stem for p in BAD.glob("*.toml"))
    assert files == sorted(BAD_CASES)
    assert len(files) >= 18
    for stem in files:
        first = (BAD / f"{stem}.toml").read_text(encoding="utf-8").splitlines()[0]
        assert first.startswith("# BROKEN: ") and len(first) > len("# BROKEN: ") + 5, stem


@pytest.mark.parametrize("stem", sorted(BAD_CASES))
def test_bad_file_raises_config_error_in_process(stem):
    # Checks: loading (and, for geometric faults, laying out) each broken file raises ConfigError
    # whose .file is the path and whose .key is the expected key path, and nothing else.
    key, fragments = BAD_CASES[stem]
    path = BAD / f"{stem}.toml"
    with pytest.raises(ConfigError) as info:
        layout_from_config(load_config(path))
    assert info.value.file == str(path)
    assert info.value.key == (key or "")
    for fragment in fragments:
        assert fragment in str(info.value)


@pytest.mark.parametrize("stem", sorted(BAD_CASES))
def test_bad_file_geometry_cli(stem, tmp_path, good_results):
    # Checks for `beltdyn geometry BROKEN.toml`: exit 2, one-line stderr naming the file and the key
    # path, no traceback, no output file or temp file created, an existing results file untouched.
    key, fragments = BAD_CASES[stem]
    path = BAD / f"{stem}.toml"
    check_rejected_both_ways(tmp_path, good_results, ["geometry", str(path)], file=str(path), key=key,
                             fragments=fragments)


@pytest.mark.parametrize("command", ["static", "modal"])
@pytest.mark.parametrize("stem", PIPELINE_SUBSET)
def test_bad_file_static_and_modal_cli(command, stem, tmp_path, good_results):
    # Checks the same as the geometry test for `static` and `modal` on a representative subset;
    # on the existing file the run also passes --force, which must not make a bad run touch it.
    key, fragments = BAD_CASES[stem]
    path = BAD / f"{stem}.toml"
    check_rejected_both_ways(tmp_path, good_results, [command, str(path)], file=str(path), key=key,
                             fragments=fragments, force_on_existing=True)


@pytest.mark.parametrize(("command", "assignment", "key", "fragments"), BAD_SETS,
                         ids=[f"{c}:{a}" for c, a, _, _ in BAD_SETS])
def test_bad_set_cli(command, assignment, key, fragments, tmp_path, good_results):
    # Checks a bad `--set` (no '=', unknown key, wrong type, index out of range, not a TOML literal,
    # NaN, unknown pulley name, unknown top-level key) on the good smoke config: exit 2, one line
    # naming the config file and the key (or the --set assignment), no traceback, no file touched.
    check_rejected_both_ways(tmp_path, good_results, [command, str(SMOKE), "--set", assignment],
                             file=str(SMOKE), key=key, fragments=fragments)


def test_missing_config_file(tmp_path, good_results):
    # Checks: a missing config file (relative path, default output path) and a directory given as
    # the config exit 2 with the path in a one-line message; no results/ folder or file is created.
    (tmp_path / "a_dir.toml").mkdir()
    r_missing, r_dir = run_cli((["geometry", "nope.toml"], tmp_path), (["static", "a_dir.toml", "-o", "x.h5"], tmp_path))
    assert_rejected(r_missing, "nope.toml", None, ["file not found"])
    assert_rejected(r_dir, "a_dir.toml", None, ["cannot read"])
    assert sorted(os.listdir(tmp_path)) == ["a_dir.toml"]


# ---------------------------------------------------------------------------------- --set works
def test_set_overrides_change_the_loaded_values():
    # Checks: --set by dotted key, by list index, by pulley name and by numeric dotted index take
    # effect; a bare word is a string; an integer literal for a float key gives a float; nothing else changes.
    base = load_config(SMOKE)
    cfg = load_config(SMOKE, ["tension.target=400", "pulleys[0].radius=0.04", "pulleys.C.mass=8.0",
                              "model.curvature=exact", "pulleys.1.inertia=0.03"])
    assert cfg.tension.target == 400.0 and isinstance(cfg.tension.target, float)
    assert cfg.pulleys[0].radius == 0.04
    assert cfg.pulleys[1].mass == 8.0
    assert cfg.model.curvature == "exact"
    assert cfg.pulleys[1].inertia == 0.03
    expected = replace(base, tension=replace(base.tension, target=400.0), model=replace(base.model, curvature="exact"),
                       pulleys=(replace(base.pulleys[0], radius=0.04),
                                replace(base.pulleys[1], mass=8.0, inertia=0.03)))
    assert cfg == expected
    # later --set of the same key wins
    assert load_config(SMOKE, ["tension.target=300", "tension.target=250"]).tension.target == 250.0


def test_set_reaches_the_cli_and_other_config_is_refused_unless_force(tmp_path, good_results):
    # Checks: writing into an existing results file of a different configuration (here: the same file
    # with two --set overrides) is refused with exit 2, a one-line message naming the output file,
    # and the file unchanged; with --force it succeeds and the file then records the overridden
    # configuration's hash (so repeated --set reached the CLI); the same configuration is then
    # accepted without --force.
    out = tmp_path / "res.h5"
    shutil.copy2(good_results, out)
    before = sha256(out)
    sets = ["--set", "tension.target=300", "--set", "pulleys.C.mass=8.0"]
    (refused,) = run_cli((["geometry", str(SMOKE), *sets, "-o", "res.h5"], tmp_path))
    line = assert_rejected(refused, "res.h5", None, ["holds results of a different configuration", "--force"])
    assert "Traceback" not in line
    assert sha256(out) == before
    assert sorted(os.listdir(tmp_path)) == ["res.h5"]

    (forced,) = run_cli((["geometry", str(SMOKE), *sets, "-o", "res.h5", "--force"], tmp_path))
    assert forced.returncode == 0, forced.stdout + forced.stderr
    assert sha256(out) != before
    new_hash = config_hash(load_config(SMOKE, ["tension.target=300", "pulleys.C.mass=8.0"]))
    assert read_root_attrs(out)["config_sha256"] == new_hash
    assert new_hash != config_hash(load_config(SMOKE))

    (same,) = run_cli((["static", str(SMOKE), *sets, "-o", "res.h5"], tmp_path))
    assert same.returncode == 0, same.stdout + same.stderr
    assert sorted(os.listdir(tmp_path)) == ["res.h5"]


# ------------------------------------------------------------------- resolved TOML and hashing
@pytest.mark.parametrize("path", ALL_CONFIGS, ids=[f"{p.parent.name}/{p.name}" for p in ALL_CONFIGS])
def test_resolved_toml_round_trips(path):
    # Checks: config_from_dict(tomllib.loads(resolved_toml(cfg))) == cfg (ignoring `source`) and the
    # hash is the same, for every shipped config.
    cfg = load_config(path)
    back = config_from_dict(tomllib.loads(resolved_toml(cfg)))
    assert replace(back, source=cfg.source) == cfg
    assert config_hash(back) == config_hash(cfg)
    assert resolved_toml(back) == resolved_toml(cfg)


_finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=150, deadline=None)
@given(direction=st.tuples(_finite, _finite).filter(lambda v: math.hypot(*v) > 1e-12),
       stiffness=st.tuples(st.floats(0, 1e9), st.floats(0, 1e9)),
       title=st.text(max_size=20),
       target=st.floats(min_value=1e-3, max_value=1e4))
def test_resolved_toml_round_trips_property(direction, stiffness, title, target):
    # Checks the round trip and hash stability for arbitrary slide directions (normalized on input:
    # re-normalizing the resolved unit vector must not change it; [1, 1] used to), bearing
    # stiffness pairs, titles with any characters and tension targets.
    raw = tomllib.loads(SMOKE.read_text(encoding="utf-8"))
    raw["title"] = title
    raw["tension"]["target"] = target
    raw["pulleys"][0]["slide_direction"] = list(direction)
    raw["pulleys"][1].update(support="bearing", bearing_stiffness=list(stiffness))
    cfg = config_from_dict(raw)
    back = config_from_dict(tomllib.loads(resolved_toml(cfg)))
    assert back == cfg
    assert config_hash(back) == config_hash(cfg)
    assert with_overrides(cfg, []) == cfg


def test_slide_direction_one_one_round_trips():
    # Checks the regression behind the config.py fix: slide_direction = [1, 1] survives the resolved
    # TOML, with_overrides and the hash unchanged (the results file's config_sha256 must be
    # reproducible from its own stored config).
    cfg = load_config(SMOKE, ["pulleys[0].slide_direction=[1.0, 1.0]"])
    assert math.isclose(math.hypot(*cfg.pulleys[0].slide_direction), 1.0, rel_tol=0, abs_tol=1e-15)
    back = config_from_dict(tomllib.loads(resolved_toml(cfg)))
    assert back.pulleys[0].slide_direction == cfg.pulleys[0].slide_direction
    assert config_hash(back) == config_hash(cfg)
    assert config_hash(with_overrides(cfg, [])) == config_hash(cfg)


def test_config_hash_stable_and_sensitive(tmp_path):
    # Checks: the hash is the same on reloading, for a copy at another path, and for the resolved
    # TOML written out (comments, key order and defaults do not matter); it changes when any value
    # changes, even slightly, and when a default is overridden by a different value.
    cfg = load_config(SMOKE)
    h = config_hash(cfg)
    assert len(h) == 64 and h == config_hash(load_config(SMOKE))
    copy = tmp_path / "copy.toml"
    shutil.copyfile(SMOKE, copy)
    assert config_hash(load_config(copy)) == h
    resolved = tmp_path / "resolved.toml"
    resolved.write_text(resolved_toml(cfg), encoding="utf-8")
    assert config_hash(load_config(resolved)) == h
    assert config_hash(load_config(SMOKE, ["static.tolerance=1e-10"])) == h  # the default, made explicit
    changed = {config_hash(with_overrides(cfg, [a])) for a in
               ["tension.target=400", "pulleys[1].mass=7.82691", "model.curvature=exact", "mesh.elements_per_span=3",
                "title=other", "belt.length=1.7924"]}
    assert len(changed) == 6 and h not in changed


# --------------------------------------------------------------------------- help and version
def test_help_and_version(tmp_path):
    # Checks: `beltdyn --help` and `beltdyn geometry --help` exit 0 and list the commands / options;
    # `beltdyn --version` prints "beltdyn <version>".
    top, geo, ver = run_cli((["--help"], tmp_path), (["geometry", "--help"], tmp_path), (["--version"], tmp_path))
    for r in (top, geo, ver):
        assert r.returncode == 0, r.stdout + r.stderr
        assert "Traceback" not in r.stdout + r.stderr
    for command in ("geometry", "static", "modal", "paper"):
        assert command in top.stdout
    for option in ("--output", "--set", "--force"):
        assert option in geo.stdout
    assert ver.stdout.strip() == f"beltdyn {beltdyn.__version__}"
    assert os.listdir(tmp_path) == []


# ------------------------------------------------------------------ one declaration per table
TRANSIENT_SMALL = ROOT / "configs" / "examples" / "bench_transient_small.toml"


def _declared_classes():
    from beltdyn.config import schema as c

    return [c.Belt, c.Pulley, c.Tension, c.Mesh, c.ModelOptions, c.StaticOptions, c.ModalOptions, c.Rotation,
            c.Record, c.Damping, c.SpectrumOptions, c.TransientOptions, c.SweepTable, c.DriveConfig,
            c._TorqueEntry, c._HubForceEntry]


def test_every_key_is_declared_once_with_a_doc():
    # Checks: every field of the TOML-facing dataclasses (but DriveConfig.source) is declared with its
    # kind and a one-line doc; valid_keys() is derived from them (the keys it listed before come first,
    # the transient and sweep keys follow); key_docs() gives each a kind, a default and a doc.
    from dataclasses import fields

    from beltdyn.config import key_docs, valid_keys

    for cls in _declared_classes():
        for f in fields(cls):
            if (cls.__name__, f.name) in (("DriveConfig", "source"), ("Belt", "derived")):  # not TOML keys
                assert "key" not in f.metadata
                continue
            assert "key" in f.metadata and f.metadata["key"].doc, (cls.__name__, f.name)
    keys = valid_keys()
    assert keys[:10] == ["title", "belt.length", "belt.EA", "belt.EI", "belt.mass_per_length", "belt.section",
                         "belt.ribs", "belt.wraps", "belt.axial_law", "pulleys[i].name"]
    for k in ("modal.solver", "transient.accuracy", "transient.fmax", "transient.max_output_mb",
              "transient.damping.rayleigh_mass", "transient.rotation[i].speed", "transient.torque[i].table",
              "transient.hub_force[i].constant", "sweep.params"):
        assert k in keys, k
    assert len(set(keys)) == len(keys)
    docs = {d.key: d for d in key_docs()}
    assert list(docs) == keys
    assert all(d.doc and d.kind and d.default for d in docs.values())
    # radius or effective_diameter (issue 29): neither is required alone (tests/test_belt_sections.py)
    assert docs["pulleys[i].radius"].default == "not set" and docs["pulleys[i].radius"].units == "m"
    assert docs["pulleys[i].radius"].kind == "number > 0"
    assert docs["pulleys[i].slide_direction"].default == "[1.0, 0.0]"
    assert docs["transient.accuracy"].kind == "number in (0, 0.1]" and docs["transient.accuracy"].default == "not set"
    assert docs["transient.fmax"].units == "Hz"
    assert docs["transient.max_output_mb"].default == "1000.0"


def _full_config(tmp_path: Path):
    """The small transient bench with every kind of key set: a bearing pulley, a slide range, a driver,
    a torque from a CSV table, a hub force, the new transient keys and a [sweep] table."""
    from beltdyn.config import config_to_dict

    (tmp_path / "torque.csv").write_text("time, torque\n0.0, 0.0\n0.01, 2.0\n1.0, 2.0\n", encoding="utf-8")
    raw = config_to_dict(load_config(TRANSIENT_SMALL))
    raw["pulleys"][0].update(slide_range=[-0.1, 0.2], driver=True)
    raw["pulleys"].append({"name": "B", "center": [0.55, -0.3], "radius": 0.03, "mass": 1.0, "inertia": 1e-3,
                           "side": "backside", "support": "bearing", "bearing_stiffness": [1e6, 2e6]})
    raw["transient"].update(accuracy=0.01, fmax=400.0, max_output_mb=50.0)
    raw["transient"]["torque"] = [{"pulley": "C", "constant": 1.0, "amplitude": 0.5, "frequency": 10.0,
                                   "table": "torque.csv"}]
    raw["transient"]["hub_force"] = [{"pulley": "B", "amplitude": [1.0, 0.0], "frequency": 120.0}]
    raw["sweep"] = {"analysis": "modal", "zip": True,
                    "params": {"tension.target": "100:200:3", "model.curvature": ["exact", "linear", "none"]}}
    return config_from_dict(raw, file=str(tmp_path / "drive.toml"))


def test_config_to_dict_round_trips_every_kind_of_key(tmp_path):
    # Checks: config_from_dict(config_to_dict(cfg)) == cfg with every kind of key set (bearing pair, slide
    # range, torque table with its sha256, hub force, sweep params, the new transient keys), through the
    # resolved TOML text as well; the CSV table's columns are read again.
    from beltdyn.config import config_to_dict

    cfg = _full_config(tmp_path)
    t = cfg.transient
    assert (t.accuracy, t.fmax, t.max_output_mb) == (0.01, 400.0, 50.0)
    assert [ld.kind for ld in t.loads] == ["torque", "hub_force"]
    assert t.loads[0].signals[0].table_time == (0.0, 0.01, 1.0) and len(t.loads[0].signals[0].table_sha256) == 64
    assert [s.amplitude for s in t.loads[1].signals] == [1.0, 0.0]
    assert cfg.sweep.params == (("tension.target", "100:200:3"), ("model.curvature", '"exact","linear","none"'))
    assert config_from_dict(config_to_dict(cfg), file=cfg.source) == cfg
    text = resolved_toml(cfg)
    back = config_from_dict(tomllib.loads(text), file=cfg.source)
    assert back == cfg and resolved_toml(back) == text
    assert back.transient.loads[0].signals[0].table_value == (0.0, 2.0, 2.0)
    resolved = tomllib.loads(text)
    assert resolved["transient"]["max_output_mb"] == 50.0 and resolved["pulleys"][2]["bearing_stiffness"] == [1e6, 2e6]
    assert resolved["pulleys"][0]["bearing_stiffness"] == 2425300.0  # a slide's one stiffness: a number


# ----------------------------------------------------------------------- the new transient keys
def test_transient_accuracy_fmax_and_max_output_defaults_and_hash():
    # Checks: the new keys default to None / None / 1000 MB and, at these defaults, are not written to
    # the resolved TOML, so the hash of every shipped transient config is what it was; set, they are.
    cfg = load_config(TRANSIENT_SMALL)
    assert (cfg.transient.accuracy, cfg.transient.fmax, cfg.transient.max_output_mb) == (None, None, 1000.0)
    resolved = tomllib.loads(resolved_toml(cfg))["transient"]
    assert not {"accuracy", "fmax", "max_output_mb"} & set(resolved)
    assert config_hash(load_config(TRANSIENT_SMALL, ["transient.max_output_mb=1000"])) == config_hash(cfg)
    changed = load_config(TRANSIENT_SMALL, ["transient.accuracy=0.02", "transient.fmax=250", "transient.max_output_mb=5"])
    assert (changed.transient.accuracy, changed.transient.fmax, changed.transient.max_output_mb) == (0.02, 250.0, 5.0)
    assert isinstance(changed.transient.fmax, float)
    assert config_hash(changed) != config_hash(cfg)
    assert with_overrides(changed, []) == changed


@pytest.mark.parametrize(("sets", "key", "fragment"), [
    (["transient.accuracy=0.01"], "transient.fmax", "missing key: transient.accuracy is given"),
    (["transient.fmax=300"], "transient.accuracy", "missing key: transient.fmax is given"),
    (["transient.accuracy=0", "transient.fmax=300"], "transient.accuracy", "must be in (0, 0.1], got 0"),
    (["transient.accuracy=0.5", "transient.fmax=300"], "transient.accuracy", "must be in (0, 0.1], got 0.5"),
    (["transient.accuracy=-0.1", "transient.fmax=300"], "transient.accuracy", "must be in (0, 0.1], got -0.1"),
    (["transient.accuracy=0.01", "transient.fmax=0"], "transient.fmax", "must be > 0, got 0"),
    (["transient.accuracy=0.01", "transient.fmax='high'"], "transient.fmax", "must be a number, got 'high'"),
    (["transient.max_output_mb=-1"], "transient.max_output_mb", "must be > 0, got -1"),
    (["transient.max_output_mb=true"], "transient.max_output_mb", "must be a number, got true"),
    (["transient.max_output_md=5"], "transient.max_output_md", "did you mean 'max_output_mb'?"),
])
def test_transient_accuracy_fmax_and_max_output_errors(sets, key, fragment):
    # Checks: range and type errors of the new keys, and accuracy / fmax given alone (the error names
    # the missing key), each a ConfigError with the file and the key path.
    with pytest.raises(ConfigError) as info:
        load_config(TRANSIENT_SMALL, sets)
    assert info.value.file == str(TRANSIENT_SMALL) and info.value.key == key
    assert fragment in str(info.value)


@pytest.mark.parametrize(("sets", "key", "fragment"), [
    (["transient.damping.rayleigh_mas=1"], "transient.damping.rayleigh_mas", "did you mean 'rayleigh_mass'?"),
    (["transient.rotation[0].frequncy=1"], "transient.rotation[0].frequncy", "did you mean 'frequency'?"),
    (["transient.rotation=[{speed=1.0}]"], "transient.rotation[0].pulley", "missing key"),
    (["transient.hub_force=[{pulley='A', constant=[1.0]}]"], "transient.hub_force[0].constant",
     "must be a list of 2 numbers"),
    (["transient.torque=[{pulley='A', amplitud=1.0}]"], "transient.torque[0].amplitud", "did you mean 'amplitude'?"),
    (["transient.torque=[{pulley='Z'}]"], "transient.torque[0].pulley", "no pulley named 'Z'"),
    (["transient.spectrum.window='hamming'"], "transient.spectrum.window", "must be one of 'hann', 'rect', 'flattop'"),
    (["sweep.analysis='fast'"], "sweep.analysis", "must be one of 'static', 'modal', 'transient'"),
])
def test_nested_tables_name_the_key_path(sets, key, fragment):
    # Checks: the generic parse gives tables nested in [transient] and [sweep] the same errors as the
    # top-level ones: unknown keys with a suggestion, missing keys and type errors, with the key path.
    with pytest.raises(ConfigError) as info:
        load_config(TRANSIENT_SMALL, sets)
    assert info.value.key == key
    assert fragment in str(info.value)


def test_transient_accuracy_without_fmax_cli(tmp_path):
    # Checks the real CLI on a small file: accuracy without fmax exits 2 with one line naming the file
    # and transient.fmax, no traceback, nothing written.
    path = tmp_path / "drive.toml"
    path.write_text(TRANSIENT_SMALL.read_text(encoding="utf-8").replace(
        'start = "static"', 'start = "static"\naccuracy = 0.01', 1), encoding="utf-8")
    (r,) = run_cli((["geometry", "drive.toml", "-o", "out.h5"], tmp_path))
    assert_rejected(r, "drive.toml", "transient.fmax", ["missing key: transient.accuracy is given"])
    assert sorted(os.listdir(tmp_path)) == ["drive.toml"]


# ------------------------------------------------------------------------------ small defects
def test_config_with_utf8_byte_order_mark_is_read(tmp_path):
    # Checks: a config saved with a UTF-8 byte order mark (some Windows editors) is read like the same
    # file without it, by load_config and by the CLI (it used to be "Invalid statement (line 1, column 1)").
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + SMOKE.read_bytes())
    assert config_hash(load_config(path)) == config_hash(load_config(SMOKE))
    assert replace(load_config(path), source="") == replace(load_config(SMOKE), source="")
    (r,) = run_cli((["geometry", "bom.toml", "-o", "out.h5"], tmp_path))
    assert r.returncode == 0, r.stdout + r.stderr
    assert read_root_attrs(tmp_path / "out.h5")["config_sha256"] == config_hash(load_config(SMOKE))


def _torque_table_config(tmp_path: Path, table: bytes) -> Path:
    (tmp_path / "torque.csv").write_bytes(table)
    path = tmp_path / "drive.toml"
    path.write_text(TRANSIENT_SMALL.read_text(encoding="utf-8")
                    + '\n[[transient.torque]]\npulley = "A"\ntable = "torque.csv"\n', encoding="utf-8")
    return path


def test_torque_table_with_byte_order_mark_keeps_its_first_row(tmp_path):
    # Checks: a CSV load table saved with a byte order mark and data on its first line keeps that row
    # (the mark used to make it unreadable, and it was skipped silently as a header).
    path = _torque_table_config(tmp_path, b"\xef\xbb\xbf0.0, 1.0\n0.5, 2.0\n1.0, 3.0\n")
    sig = load_config(path).transient.loads[0].signals[0]
    assert sig.table_time == (0.0, 0.5, 1.0) and sig.table_value == (1.0, 2.0, 3.0)
    assert sig.table_sha256 == sha256(tmp_path / "torque.csv")


@pytest.mark.parametrize(("name", "fragment"), [
    ("A ", "must not begin or end with white space, got 'A '"),
    (" C", "must not begin or end with white space, got ' C'"),
    ("C\\t", "must not begin or end with white space"),
    ("", "must be a non-empty string, got ''"),
    ("  ", "must be a non-empty string, got '  '"),
])
def test_pulley_name_with_surrounding_white_space_is_rejected(tmp_path, name, fragment):
    # Checks: a pulley name with white space around it (so "A" and "A " could both exist) or an empty
    # name is rejected with the key path, by load_config on a small file; the duplicate check stays.
    path = tmp_path / "drive.toml"
    path.write_text(SMOKE.read_text(encoding="utf-8").replace('name = "C"', f'name = "{name}"'), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert info.value.file == str(path) and info.value.key == "pulleys[1].name"
    assert fragment in str(info.value)


def test_pulley_name_white_space_cli(tmp_path):
    # Checks the same at the command line: exit 2, one line with the file and pulleys[1].name.
    path = tmp_path / "drive.toml"
    path.write_text(SMOKE.read_text(encoding="utf-8").replace('name = "C"', 'name = "A "'), encoding="utf-8")
    (r,) = run_cli((["static", "drive.toml", "-o", "out.h5"], tmp_path))
    assert_rejected(r, "drive.toml", "pulleys[1].name", ["must not begin or end with white space"])
    assert sorted(os.listdir(tmp_path)) == ["drive.toml"]


# Bad input that used to end in a traceback: (assignment, key path named, fragment).


def test_gauss_points_bound_is_the_quadrature_table():
    # Checks: model.gauss_points is bounded by what beltdyn.model.ancf can integrate (it used to pass the
    # config and fail later with a ValueError traceback), with the key path in the message.
    from beltdyn.model import ancf
    from beltdyn.config import MAX_GAUSS_POINTS

    assert MAX_GAUSS_POINTS == ancf._MAX_GAUSS
    assert load_config(SMOKE, [f"model.gauss_points={MAX_GAUSS_POINTS}"]).model.gauss_points == MAX_GAUSS_POINTS
    with pytest.raises(ConfigError) as info:
        load_config(SMOKE, [f"model.gauss_points={MAX_GAUSS_POINTS + 1}"])
    assert info.value.key == "model.gauss_points" and f"must be in [1, {MAX_GAUSS_POINTS}]" in str(info.value)


TRACEBACK_SETS = [
    ("belt.0=1", "belt.0", "unknown key '0'"),
    ("belt[0].x=1", "belt.0", "unknown key '0'"),
    ("belt.EA=1" + "0" * 400, "belt.EA", "must be finite"),
    ("model.gauss_points=100000", "model.gauss_points", "must be in [1, 64], got 100000"),
]


def test_bad_input_that_used_to_raise_a_traceback(tmp_path):
    # Checks: an integer key put into a table by --set, an integer beyond the float range and a
    # quadrature order beyond the table are exit 2 with the file and the key path, no traceback.
    calls = []
    for i, (assignment, _, _) in enumerate(TRACEBACK_SETS):
        (tmp_path / str(i)).mkdir()
        calls.append((["modal", str(SMOKE), "--set", assignment, "-o", "out.h5"], tmp_path / str(i)))
    for (assignment, key, fragment), r, (_, cwd) in zip(TRACEBACK_SETS, run_cli(*calls), calls):
        assert_rejected(r, str(SMOKE), key, [fragment])
        assert os.listdir(cwd) == [], assignment


def test_sweep_params_list_items_must_be_values():
    # Checks: a [sweep.params] list holds numbers, strings or booleans; a nested list or a table in it
    # is an error with the key path (it used to become a SPEC string that failed later, in the sweep).
    for value in ("[{a=1}]", "[[1, 2]]"):
        with pytest.raises(ConfigError) as info:
            load_config(TRANSIENT_SMALL, [f"sweep.params.x={value}"])
        assert info.value.key == "sweep.params.x"
        assert "must be a SPEC string or a list of numbers, strings or booleans" in str(info.value)
    cfg = load_config(TRANSIENT_SMALL, ["sweep.params.x=[1, 2.5, true, 'exact']"])
    assert cfg.sweep.params == (("x", '1,2.5,true,"exact"'),)


def test_torque_table_bad_first_row_is_not_taken_for_a_header(tmp_path):
    # Checks: a header line (no number in it) is still skipped, but a first data row with a typo is
    # an error naming the line, not a header silently dropped.
    ok = load_config(_torque_table_config(tmp_path, b"t (s), torque (N m)\n0.0, 1.0\n1.0, 3.0\n"))
    assert ok.transient.loads[0].signals[0].table_time == (0.0, 1.0)
    path = _torque_table_config(tmp_path, b"0.0, 1.0x\n0.5, 2.0\n1.0, 3.0\n")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert info.value.key == "transient.torque[0].table"
    assert "line 1: not numbers" in str(info.value)
