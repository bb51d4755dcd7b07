"""The real `beltdyn static` / `modal` / `paper` commands on small configs: files, exit codes, failures."""

from __future__ import annotations

import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from beltdyn.results.io import read_group
from processes import BELTDYN  # tests/processes.py

ROOT = Path(__file__).resolve().parents[1]


def beltdyn(*args, cwd):
    return subprocess.run([*BELTDYN, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=120)


def test_modal_command_writes_all_groups(tmp_path):
    # The smoke bench: exit 0, /geometry /static /modal complete, tension at the target (1e-8), the
    # frequencies equal to an in-process run (the CLI only wires), and every dataset has units.
    out = tmp_path / "m.h5"
    r = beltdyn("modal", ROOT / "configs/smoke/two_pulley.toml", "-o", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    st = read_group(out, "static")
    assert st["attrs"]["status"] == "complete"
    assert float(st["variables"]["mean_tension"]) == pytest.approx(200.0, rel=1e-8)
    md = read_group(out, "modal")
    assert md["attrs"]["status"] == "complete" and md["attrs"]["n_rigid"] == 1
    from beltdyn.config import load_config
    from beltdyn.pipeline import analyse

    cfg = load_config(ROOT / "configs/smoke/two_pulley.toml")
    ref = analyse(cfg, modal=True).modal
    np.testing.assert_allclose(md["variables"]["frequency"], ref.frequency, rtol=1e-12)
    with h5py.File(out) as f:
        def check(name, obj):
            if isinstance(obj, h5py.Dataset):
                assert "units" in obj.attrs, name
                assert obj.dtype.kind not in ("b", "c"), name
        f.visititems(check)


def test_solver_failure_exit_1_and_failed_group(tmp_path):
    # A slack belt without bending stiffness is a mechanism: exit 1, a one-line message naming the
    # analysis and a DOF, /modal marked failed (no frequencies), /geometry and /static complete.
    from beltdyn.config import load_config
    from beltdyn.model.geometry import layout_from_config

    cfg = load_config(ROOT / "configs/smoke/two_pulley.toml", ["pulleys[0].adjustable=false"])
    length = layout_from_config(cfg).belt_length
    text = (ROOT / "configs/smoke/two_pulley.toml").read_text()
    text = text.replace("adjustable = true", "adjustable = false").replace("target = 200.0", "")
    text = text.replace("EI = 0.02", "EI = 0.0").replace("length = 1.7923", f"length = {length!r}")
    cfg_path = tmp_path / "slack.toml"
    cfg_path.write_text(text.replace("[tension]\n", ""))
    out = tmp_path / "slack.h5"
    r = beltdyn("modal", cfg_path, "-o", out, cwd=tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: modal:") and "span" in lines[0]
    assert "Traceback" not in r.stdout + r.stderr
    md = read_group(out, "modal")
    assert md["attrs"]["status"] == "failed" and "mechanism" in md["attrs"]["error"]
    assert "frequency" not in md["variables"]
    assert read_group(out, "static")["attrs"]["status"] == "complete"


def test_paper_command_writes_tables(tmp_path):
    # `beltdyn paper` reproduces the 24 modes (< 0.5 %) and writes tables.md and one file per case.
    r = beltdyn("paper", "--outdir", tmp_path / "paper", "--configs", ROOT / "configs/paper", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    table = (tmp_path / "paper" / "tables.md").read_text()
    assert table.count("\n| T") == 24
    assert sorted(p.name for p in (tmp_path / "paper").glob("*.h5")) == [
        "bench_EI100.h5", "bench_T200.h5", "bench_T400.h5"]
    worst = float(r.stdout.split("largest difference to the paper's theoretical values:")[1].split("%")[0])
    assert worst < 0.5
