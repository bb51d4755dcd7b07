"""`beltdyn info` and recovery keyed on the file alone (issue 26, item 5), and `--duration` shorter than
the spectral window's start (item 8), each through the real CLI.

A transient killed with SIGKILL leaves /transient `running` with its samples in the stream journal;
`beltdyn info` (which only reads otherwise) recovers them: plain h5py then sees the group
`interrupted` with exactly the samples a reader saw in the journal after the kill (compared row by
row with `read_group` of the journal before the recovery). A command of another configuration on
such a file recovers it too before it refuses the file (the old behaviour recovered only with the
killed command's own configuration and overrides).
"""

from __future__ import annotations

import functools
import json
import signal
import tomllib
from pathlib import Path

import h5py
import numpy as np

import processes  # tests/processes.py
from processes import BELTDYN
from beltdyn.results.io import read_group

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "configs" / "examples" / "bench_transient_small.toml"  # duration 2 s, spectrum.start 1 s
LONG = ("--duration", "200", "--step", "2e-5")  # a transient that never ends within a test


_env = processes.plain_env


run = functools.partial(processes.run, timeout=300)


samples = processes.journal_samples


def killed_transient(out: Path, cwd: Path) -> tuple[int, dict]:
    """A long transient into `out`, killed with SIGKILL once its journal has grown: (its pid, the
    /transient a reader sees afterwards, samples read from the journal)."""
    proc = processes.popen([*BELTDYN, "transient", str(SMALL), "-o", str(out), *LONG], cwd=cwd, env=_env())
    try:
        assert processes.wait_for(lambda: samples(out) > 0, timeout=120), "the transient did not start streaming"
        first = samples(out)
        assert processes.wait_for(lambda: samples(out) > first, timeout=30), "the journal did not grow"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    live = read_group(out, "transient")
    assert live["attrs"]["status"] == "running" and live["writer"]["alive"] is False
    with h5py.File(out, "r") as f:  # before the recovery plain h5py sees no sample
        assert "time" not in f["transient"]
    return proc.pid, live


def assert_recovered(out: Path, live: dict) -> None:
    """Plain h5py sees /transient interrupted with every journaled sample, equal to the journal's."""
    n = len(live["coords"]["time"])
    assert n > 0
    with h5py.File(out, "r") as f:
        g = f["transient"]
        assert g.attrs["status"] == "interrupted"
        assert "ended without closing /transient" in g.attrs["error"]
        assert "writer_pid" not in g.attrs and "stream_journal" not in g.attrs
        np.testing.assert_array_equal(g["time"][()], live["coords"]["time"])
        np.testing.assert_array_equal(g["span_tension"][()], live["variables"]["span_tension"])
    assert not list(out.parent.glob(f"{out.name}.parts/*.stream")), "the journal was left behind"


def test_info_on_a_complete_file_names_groups_status_title_and_hash(tmp_path):
    out = tmp_path / "s.h5"
    r = run("static", SMALL, "-o", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    with h5py.File(out, "r") as f:
        sha = f.attrs["config_sha256"]
        sha = sha.decode() if isinstance(sha, bytes) else str(sha)
    table = run("info", out, cwd=tmp_path)
    assert table.returncode == 0, table.stderr
    assert table.stderr == ""  # nothing to recover, nothing to say
    assert "Paper bench, T = 200 N" in table.stdout and sha in table.stdout
    rows = {line.split()[1]: line for line in table.stdout.splitlines() if line.startswith("│ /")}
    assert set(rows) == {"/geometry", "/static"}
    assert all("complete" in row for row in rows.values())

    as_json = run("info", out, "--json", cwd=tmp_path)
    assert as_json.returncode == 0, as_json.stderr
    data = json.loads(as_json.stdout)
    assert data["config_sha256"] == sha and data["title"].startswith("Paper bench")
    assert [(g["name"], g["status"], g["writer"]) for g in data["groups"]] == [("geometry", "complete", None),
                                                                               ("static", "complete", None)]


def test_info_on_a_missing_file_is_exit_2_naming_it(tmp_path):
    r = run("info", tmp_path / "nowhere.h5", cwd=tmp_path)
    assert r.returncode == 2
    assert "nowhere.h5: no such results file" in r.stderr and "Traceback" not in r.stderr
    assert not list(tmp_path.iterdir()), "info created something"


def test_info_on_files_that_are_not_results_is_exit_2_naming_them(tmp_path):
    text = tmp_path / "notes.h5"
    text.write_text("not HDF5\n")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = np.arange(3)
    for path, says in ((text, "cannot be read as an HDF5 file"), (other, "is not a beltdyn results file")):
        r = run("info", path, cwd=tmp_path)
        assert r.returncode == 2 and f"{path.name}: {says}" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert text.read_text() == "not HDF5\n"


def test_info_prints_a_title_with_brackets_as_written(tmp_path):
    # the title is the user's text, not console markup
    out = tmp_path / "g.h5"
    r = run("geometry", SMALL, "-o", out, "--set", 'title="Drive [bold] [v2] [/]"', cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = run("info", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "configuration: Drive [bold] [v2] [/], sha256" in r.stdout


def test_info_and_another_configuration_recover_a_killed_transient(tmp_path):
    # 1. info while the writer runs: the group running, its writer alive, never blocked by its lock
    out = tmp_path / "k.h5"
    proc = processes.popen([*BELTDYN, "transient", str(SMALL), "-o", str(out), *LONG], cwd=tmp_path, env=_env())
    try:
        assert processes.wait_for(lambda: samples(out) > 0, timeout=120), "the transient did not start streaming"
        live = run("info", out, "--json", cwd=tmp_path)
        assert live.returncode == 0, live.stderr
        group = {g["name"]: g for g in json.loads(live.stdout)["groups"]}["transient"]
        assert group["status"] == "running" and group["writer"]["pid"] == proc.pid
        assert group["writer"]["alive"] is True and group["samples"] > 0
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=30)

    # 2. after the kill: info recovers, whatever the killed command's configuration was
    live = read_group(out, "transient")
    n = len(live["coords"]["time"])
    r = run("info", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"/transient was left 'running' by pid {proc.pid}" in r.stderr and f"recovered {n} samples" in r.stderr
    row = next(line for line in r.stdout.splitlines() if line.startswith("│ /transient"))
    assert "interrupted" in row and f" {n} " in row
    assert_recovered(out, live)
    again = run("info", out, cwd=tmp_path)  # nothing left to recover
    assert again.returncode == 0 and again.stderr == ""

    # 3. a command of another configuration (another tension) on a second killed file recovers it
    # before it refuses to mix configurations (exit 2)
    other = tmp_path / "o.h5"
    pid, live = killed_transient(other, tmp_path)
    r = run("static", SMALL, "-o", other, "--set", "tension.target=250", cwd=tmp_path)
    assert r.returncode == 2 and "holds results of a different configuration" in r.stderr
    assert f"/transient was left 'running' by pid {pid}" in r.stderr
    assert_recovered(other, live)


def test_duration_before_the_spectral_window_moves_it_and_says_so(tmp_path):
    # bench_transient_small: duration 2 s, spectrum.start 1 s; --duration 0.03 s ends before it. The
    # window moves to the same fraction of the run: 1 * 0.03 / 2 = 0.015 s (closed form).
    out = tmp_path / "d.h5"
    r = run("transient", SMALL, "-o", out, "--duration", "0.03", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    said = r.stdout + r.stderr
    assert "spectral window is moved to start at 0.015 s" in said
    g = read_group(out, "transient")
    assert g["attrs"]["status"] == "complete"
    assert any("spectral window is moved to start at 0.015 s" in w for w in g["attrs"]["warnings"])
    with h5py.File(out, "r") as f:
        toml = f["provenance/config_toml"].asstr()[()]
    resolved = tomllib.loads(toml)["transient"]
    assert resolved["duration"] == 0.03 and resolved["spectrum"]["start"] == 0.015

    # a start given with --set is the user's: not moved, refused by the configuration's check
    bad = run("transient", SMALL, "-o", tmp_path / "e.h5", "--duration", "0.03", "--set",
              "transient.spectrum.start=0.5", cwd=tmp_path)
    assert bad.returncode == 2 and "transient.spectrum.start" in bad.stderr and "Traceback" not in bad.stderr


def test_info_on_a_read_only_file_with_a_dead_writer_reports_it_and_leaves_it(tmp_path):
    # a read-only results file is the user's protection: info shows the dead writer and the journal's
    # samples and says why it does not recover them; the file is not replaced
    out = tmp_path / "r.h5"
    pid, live = killed_transient(out, tmp_path)
    before = out.read_bytes()
    out.chmod(0o444)
    try:
        r = run("info", out, "--json", cwd=tmp_path)
    finally:
        out.chmod(0o644)
    assert r.returncode == 0, r.stderr
    assert f"/transient was left 'running' by pid {pid}" in r.stderr and "read-only, so it is not recovered" in r.stderr
    group = {g["name"]: g for g in json.loads(r.stdout)["groups"]}["transient"]
    assert group["status"] == "running" and group["writer"] == {"pid": pid, "host": group["writer"]["host"],
                                                                "alive": False}
    assert group["samples"] == len(live["coords"]["time"])
    assert out.read_bytes() == before
