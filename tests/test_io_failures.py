"""I/O failures are not bad input (issue 26, item 7): an OSError while the results file, a stream journal
or a group is written (a full disk) exits 1 naming the file and the error, never leaves a group
'running' behind a live-looking writer (it is marked 'failed', or left for the next command to recover
as 'interrupted'), and never harms the groups written before.

Compared against: the files' own status attributes as written before the failure (byte-for-byte for the
untouched root), and the errno text the operating system gives for ENOSPC."""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from beltdyn.results import stream as rstream
from beltdyn.results import write as rwrite
from beltdyn.results.io import GroupData, StreamWriter, Variable, WriteFailure, group_states, write_group
from beltdyn.results.journal import JournalWriter

from processes import BELTDYN

ROOT = Path(__file__).resolve().parents[1]
TRANSIENT = ROOT / "configs" / "examples" / "bench_transient_small.toml"
SHA = "d" * 64
TOML = 'title = "io failure test"\n'
FULL = os.strerror(errno.ENOSPC)  # "No space left on device"


def _earlier(path: Path) -> None:
    write_group(path, GroupData(name="static", coords={"span": np.arange(3)},
                                variables=(Variable(name="tension", data=np.array([1.0, 2.0, 3.0]), dims=("span",),
                                                    units="N"),)),
                config_toml=TOML, config_sha256=SHA)


def _disk_full(*args, **kwargs):
    raise OSError(errno.ENOSPC, FULL)


def _writer(path: Path) -> StreamWriter:
    return StreamWriter(path, "transient", series={"x": ((2,), "m", ("k",))}, coords={"k": np.arange(2)},
                        config_toml=TOML, config_sha256=SHA, flush_every=1)


def test_a_full_disk_while_streaming_marks_the_group_failed_and_exits_1(tmp_path, monkeypatch):
    path = tmp_path / "r.h5"
    _earlier(path)
    with pytest.raises(WriteFailure) as got:
        with _writer(path) as w:
            w.append(np.arange(5) * 0.1, {"x": np.ones((5, 2))})
            monkeypatch.setattr(JournalWriter, "write", _disk_full)
            monkeypatch.setattr(rstream, "_journal_series", _disk_full)  # the samples cannot be copied either
            w.append(np.array([0.5]), {"x": np.ones((1, 2))})
    assert got.value.exit_code == 1  # not the bad-input code 2
    assert str(path) in str(got.value) and FULL in str(got.value)
    states = group_states(path)
    assert states["static"].status == "complete"
    assert states["transient"].status == "failed" and FULL in states["transient"].error
    with h5py.File(path) as f:  # the journal stays named by the group, so its samples are kept
        journal = path.parent / f["transient"].attrs["stream_journal"]
        np.testing.assert_array_equal(f["static/tension"][()], [1.0, 2.0, 3.0])
    assert journal.is_file()


def test_when_not_even_the_status_can_be_written_the_group_is_left_for_recovery(tmp_path, monkeypatch):
    path = tmp_path / "r.h5"
    _earlier(path)
    with pytest.raises(WriteFailure) as got:
        with _writer(path) as w:
            w.append(np.arange(3) * 0.1, {"x": np.ones((3, 2))})
            monkeypatch.setattr(rstream, "_journal_series", _disk_full)
            monkeypatch.setattr(rstream.Transaction, "__init__", _disk_full)  # no temporary root either
    assert got.value.exit_code == 1
    notes = " ".join(getattr(got.value, "__notes__", ())) + str(got.value)
    assert "recovers" in notes and "running" in notes
    state = group_states(path)["transient"]
    assert state.status == "running" and state.writer_pid == os.getpid() and state.samples == 3
    assert group_states(path)["static"].status == "complete"


def test_a_failed_write_of_groups_exits_1_and_leaves_the_file_unchanged(tmp_path, monkeypatch):
    path = tmp_path / "r.h5"
    _earlier(path)
    before = path.read_bytes()
    monkeypatch.setattr(rwrite, "write_dataset", _disk_full)
    with pytest.raises(WriteFailure) as got:
        _earlier(path)
    assert got.value.exit_code == 1 and FULL in str(got.value) and str(path) in str(got.value)
    assert path.read_bytes() == before


@pytest.fixture
def small_disk(tmp_path):
    """A 256 kB tmpfs (mounting needs root: skipped otherwise)."""
    where = tmp_path / "disk"
    where.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(where)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    yield where
    subprocess.run(["umount", str(where)], capture_output=True)


def test_a_full_disk_through_the_cli_exits_1_and_the_next_command_recovers(small_disk):
    args = [TRANSIENT, "--set", "transient.duration=1.0", "--set", "transient.output_interval=1e-4",
            "--set", "transient.spectrum.enabled=false", "-o", small_disk / "t.h5"]
    r = subprocess.run([*BELTDYN, "transient", *map(str, args)], cwd=small_disk.parent, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 1, r.stderr
    assert str(small_disk / "t.h5") in r.stderr and FULL in r.stderr and "Traceback" not in r.stderr
    states = group_states(small_disk / "t.h5")
    assert states["geometry"].status == states["static"].status == "complete"
    transient = states["transient"]
    assert transient.status == "failed" or transient.orphaned  # never a live-looking 'running'
    # more room: the next command on the file puts it right (recovered: interrupted, or failed as marked)
    subprocess.run(["mount", "-o", "remount,size=4m", str(small_disk)], check=True)
    r = subprocess.run([*BELTDYN, "static", *map(str, args)], cwd=small_disk.parent,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert group_states(small_disk / "t.h5")["transient"].status in ("failed", "interrupted")
