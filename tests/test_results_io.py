"""Tests of beltdyn.results.io: the HDF5 results contract (layout, xarray compatibility, atomicity)."""

from __future__ import annotations

import os
import subprocess
import sys
from datetime import datetime, timedelta
from pathlib import Path

import h5py
import numpy as np
import pytest

import beltdyn
from beltdyn.results import write as rwrite
from beltdyn.errors import OutputError
from beltdyn.results.io import (
    GroupData,
    StreamWriter,
    Variable,
    check_target,
    read_group,
    read_root_attrs,
    write_group,
)

SHA = "a" * 64
OTHER_SHA = "b" * 64
TOML = 'title = "test drive"\n[belt]\nEA = 1.0e5\n'


def geometry_group(**overrides) -> GroupData:
    kw = dict(
        name="geometry",
        coords={"pulley": ["A", "C"], "component": ["x", "y"], "node": np.arange(4) * 0.25},
        coord_units={"node": "m"},
        variables=(
            Variable(name="center", data=np.array([[0.0, 0.0], [0.5, -0.1]]), dims=("pulley", "component"),
                     units="m", description="pulley centres"),
            Variable(name="radius", data=np.array([0.05, 0.0]), dims=("pulley",), units="m"),
            Variable(name="role", data=["driver", ""], dims=("pulley",), units="1"),
            Variable(name="is_idler", data=np.array([False, True]), dims=("pulley",), units="1"),
            Variable(name="teeth", data=np.array([20, 40], dtype=np.int64), dims=("pulley",), units="1"),
            Variable(name="xy", data=np.arange(8.0).reshape(4, 2), dims=("node", "component"), units="m"),
            Variable(name="wrap", data=np.array([1.5, 2.0, 3.0]), dims=("contact",), units="rad"),
            Variable(name="belt_length", data=np.float64(1.25), dims=(), units="m"),
            Variable(name="label", data="Ünïcode drive", dims=(), units="1"),
        ),
        attrs={"n_spans": 2, "tension": 150.0, "solver": "newton", "converged": True},
    )
    kw.update(overrides)
    return GroupData(**kw)


def check_contract(path: Path) -> None:
    """Every dataset has units, no bool/complex dtype, every axis of every non-scale dataset has
    exactly one attached dimension scale whose name is the dimension name and whose length matches."""
    with h5py.File(path, "r") as f:
        seen = []

        def visit(name, obj):
            if not isinstance(obj, h5py.Dataset):
                return
            seen.append(name)
            assert "units" in obj.attrs, f"{name} has no units"
            assert obj.dtype.kind not in "bc", f"{name} has dtype {obj.dtype}"
            if h5py.h5ds.is_scale(obj.id):
                assert obj.ndim == 1
                return
            for axis in range(obj.ndim):
                scales = list(obj.dims[axis].values())
                assert len(scales) == 1, f"{name} axis {axis} has {len(scales)} scales"
                assert scales[0].shape[0] == obj.shape[axis]
                assert scales[0].parent == obj.parent, f"{name}: scale not in the same group"

        f.visititems(visit)
        assert seen


# ----------------------------------------------------------------------------------------------


def test_round_trip_numeric_and_string_data_with_units_and_scales(tmp_path):
    """write_group -> h5py/read_group give back the input; units, scales, int8 for bool."""
    path = tmp_path / "out" / "results.h5"  # parent directory is created
    group = geometry_group()
    write_group(path, group, config_toml=TOML, config_sha256=SHA)

    check_contract(path)
    with h5py.File(path, "r") as f:
        g = f["geometry"]
        np.testing.assert_array_equal(g["center"][()], group.variables[0].data)
        assert list(g["pulley"].asstr()[()]) == ["A", "C"]
        assert list(g["role"].asstr()[()]) == ["driver", ""]
        assert g["is_idler"].dtype == np.int8
        assert g["teeth"].dtype == np.int64
        assert g["node"].attrs["units"] == "m"
        assert g["pulley"].attrs["units"] == "1"
        assert g["center"].attrs["description"] == "pulley centres"
        # "contact" had no coordinate values: an integer index coordinate was added
        np.testing.assert_array_equal(g["contact"][()], [0, 1, 2])
        assert h5py.h5ds.is_scale(g["contact"].id)
        assert g.attrs["status"] == "complete"
        assert "error" not in g.attrs

    out = read_group(path, "geometry")
    assert set(out["coords"]) == {"pulley", "component", "node", "contact"}
    np.testing.assert_array_equal(out["coords"]["pulley"], ["A", "C"])
    np.testing.assert_array_equal(out["coords"]["node"], [0.0, 0.25, 0.5, 0.75])
    np.testing.assert_array_equal(out["variables"]["xy"], np.arange(8.0).reshape(4, 2))
    np.testing.assert_array_equal(out["variables"]["role"], ["driver", ""])
    np.testing.assert_array_equal(out["variables"]["is_idler"], [0, 1])
    assert out["variables"]["label"] == "Ünïcode drive"
    assert float(out["variables"]["belt_length"]) == 1.25
    assert out["dims"]["center"] == ("pulley", "component")
    assert out["dims"]["wrap"] == ("contact",)
    assert out["units"]["wrap"] == "rad"
    assert out["attrs"] == {"n_spans": 2, "tension": 150.0, "solver": "newton", "converged": 1,
                            "status": "complete"}


def test_opens_in_xarray_datatree_and_dataset(tmp_path):
    """The file opens with xarray (engine h5netcdf): dims, coordinate values, data and units."""
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    write_group(path, GroupData(name="modal", coords={"mode": np.arange(1, 4)},
                                variables=(Variable(name="frequency", data=np.array([0.0, 12.5, 30.0]),
                                                    dims=("mode",), units="Hz"),)),
                config_toml=TOML, config_sha256=SHA)

    tree = xr.open_datatree(path, engine="h5netcdf")
    try:
        assert {"geometry", "modal", "provenance"} <= set(tree.children)
        assert tree.attrs["config_sha256"] == SHA
        assert tree["provenance"].ds["config_toml"].item() == TOML
        geo = tree["geometry"].ds
        assert dict(geo.sizes) == {"pulley": 2, "component": 2, "node": 4, "contact": 3}
        assert tree["modal"].ds["frequency"].attrs["units"] == "Hz"
        np.testing.assert_array_equal(tree["modal"].ds["frequency"].values, [0.0, 12.5, 30.0])  # 0 not masked
    finally:
        tree.close()

    with xr.open_dataset(path, group="geometry", engine="h5netcdf") as ds:
        assert ds["center"].dims == ("pulley", "component")
        assert list(ds["pulley"].values) == ["A", "C"]
        assert list(ds["component"].values) == ["x", "y"]
        assert ds["center"].attrs["units"] == "m"
        assert ds["pulley"].attrs["units"] == "1"
        np.testing.assert_array_equal(ds["center"].sel(pulley="C").values, [0.5, -0.1])
        np.testing.assert_array_equal(ds["radius"].values, [0.05, 0.0])
        assert list(ds["role"].values) == ["driver", ""]
        assert ds["is_idler"].dtype == np.int8
        assert ds["belt_length"].dims == ()
        assert ds["label"].item() == "Ünïcode drive"
        assert ds.attrs["status"] == "complete"
        assert ds.attrs["solver"] == "newton"


def test_root_attributes_and_provenance(tmp_path):
    """Root attrs beltdyn_version, schema_version, created_utc (ISO 8601 UTC), config_sha256 and
    the scalar string dataset /provenance/config_toml are written."""
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    attrs = read_root_attrs(path)
    assert attrs["beltdyn_version"] == beltdyn.__version__
    assert attrs["schema_version"] == beltdyn.SCHEMA_VERSION
    assert attrs["config_sha256"] == SHA
    created = datetime.fromisoformat(attrs["created_utc"])
    assert created.utcoffset() == timedelta(0)
    with h5py.File(path, "r") as f:
        ds = f["provenance/config_toml"]
        assert ds.shape == ()
        assert h5py.check_string_dtype(ds.dtype).encoding == "utf-8"
        assert ds.asstr()[()] == TOML
        assert ds.attrs["units"] == "1"

    # created_utc is kept when another group is added later
    write_group(path, GroupData(name="static", coords={}), config_toml=TOML, config_sha256=SHA)
    assert read_root_attrs(path)["created_utc"] == attrs["created_utc"]


def test_second_group_keeps_first_and_rewrite_replaces(tmp_path):
    """Adding /static keeps /geometry; writing /static again replaces its content entirely."""
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    static1 = GroupData(name="static", coords={"span": ["AB", "BA"]},
                        variables=(Variable(name="tension", data=np.array([100.0, 50.0]), dims=("span",),
                                            units="N"),
                                   Variable(name="old_only", data=np.ones(3), dims=("k",), units="1")))
    write_group(path, static1, config_toml=TOML, config_sha256=SHA)
    assert "center" in read_group(path, "geometry")["variables"]
    static2 = GroupData(name="static", coords={"span": ["AB", "BC", "CA"]},
                        variables=(Variable(name="tension", data=np.array([1.0, 2.0, 3.0]), dims=("span",),
                                            units="N"),),
                        status="failed", error="static: did not converge")
    write_group(path, static2, config_toml=TOML, config_sha256=SHA)
    out = read_group(path, "static")
    np.testing.assert_array_equal(out["variables"]["tension"], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(out["coords"]["span"], ["AB", "BC", "CA"])
    assert "old_only" not in out["variables"] and "k" not in out["coords"]
    assert out["attrs"]["status"] == "failed"
    assert out["attrs"]["error"] == "static: did not converge"
    assert "center" in read_group(path, "geometry")["variables"]
    check_contract(path)


def test_different_config_is_refused_unless_force(tmp_path):
    """Another config_sha256 -> OutputError naming the file and --force, bytes unchanged;
    force=True starts the file afresh (old groups gone)."""
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    before = path.read_bytes()
    static = GroupData(name="static", coords={})

    check_target(path, config_sha256=SHA)  # same configuration: fine
    check_target(tmp_path / "new" / "x.h5", config_sha256=SHA)  # missing file: fine
    with pytest.raises(OutputError, match="--force") as err:
        check_target(path, config_sha256=OTHER_SHA)
    assert str(path) in str(err.value)
    assert err.value.exit_code == 2
    with pytest.raises(OutputError, match="--force") as err:
        write_group(path, static, config_toml="other", config_sha256=OTHER_SHA)
    assert str(path) in str(err.value)
    with pytest.raises(OutputError, match="--force"):
        StreamWriter(path, "transient", series={"q": ((1,), "m", ("dof",))}, coords={},
                     config_toml="other", config_sha256=OTHER_SHA)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5"]

    check_target(path, config_sha256=OTHER_SHA, force=True)
    write_group(path, static, config_toml="other", config_sha256=OTHER_SHA, force=True)
    attrs = read_root_attrs(path)
    assert attrs["config_sha256"] == OTHER_SHA
    with h5py.File(path, "r") as f:
        assert set(f) == {"static", "provenance"}
        assert f["provenance/config_toml"].asstr()[()] == "other"


def test_failure_midway_leaves_target_unchanged_and_no_temp_file(tmp_path, monkeypatch):
    """An exception (or KeyboardInterrupt) raised in the middle of writing a group leaves the
    existing file byte-for-byte unchanged and removes the temporary file; with no existing file,
    nothing is created."""
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    before = path.read_bytes()
    real = rwrite.write_dataset
    calls = {"n": 0}

    def failing(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise RuntimeError("disk on fire")
        return real(*args, **kwargs)

    monkeypatch.setattr(rwrite, "write_dataset", failing)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_group(path, geometry_group(name="static"), config_toml=TOML, config_sha256=SHA)
    assert calls["n"] == 3
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5"]

    calls["n"] = 0
    with pytest.raises(RuntimeError):  # replacing an existing group: old content survives
        write_group(path, geometry_group(variables=()), config_toml=TOML, config_sha256=SHA)
    assert path.read_bytes() == before

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(rwrite, "fsync_file", interrupt)  # within the commit, before the rename
    monkeypatch.setattr(rwrite, "write_dataset", real)
    with pytest.raises(KeyboardInterrupt):
        write_group(path, geometry_group(name="modal"), config_toml=TOML, config_sha256=SHA)
    assert path.read_bytes() == before
    with pytest.raises(KeyboardInterrupt):
        write_group(tmp_path / "fresh.h5", geometry_group(), config_toml=TOML, config_sha256=SHA)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5"]


def test_non_hdf5_foreign_or_corrupt_target_is_refused_unless_force(tmp_path):
    """A non-HDF5 file, an HDF5 file that is not a beltdyn results file, or a corrupt (truncated)
    beltdyn file at the target -> OutputError naming it and saying that --force replaces it, the
    file untouched; with force it is replaced by a fresh results file. A directory is always refused."""
    text = tmp_path / "results.h5"
    text.write_text("this is my thesis\n")
    foreign = tmp_path / "other.h5"
    with h5py.File(foreign, "w") as f:
        f["data"] = np.arange(3)
    corrupt = tmp_path / "corrupt.h5"
    write_group(corrupt, geometry_group(), config_toml=TOML, config_sha256=SHA)
    corrupt.write_bytes(corrupt.read_bytes()[:1500])  # the HDF5 signature survives, the rest is cut
    for path in (text, foreign, corrupt):
        content = path.read_bytes()
        with pytest.raises(OutputError) as err:
            check_target(path, config_sha256=SHA)
        assert str(path) in str(err.value) and "--force replaces it" in str(err.value)
        with pytest.raises(OutputError) as err:
            write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
        assert str(path) in str(err.value) and "--force replaces it" in str(err.value)
        assert path.read_bytes() == content
        check_target(path, config_sha256=SHA, force=True)
        write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA, force=True)
        assert read_root_attrs(path)["config_sha256"] == SHA
        assert set(h5py.File(path, "r")) == {"geometry", "provenance"}
        check_contract(path)
    with pytest.raises(OutputError):
        check_target(tmp_path, config_sha256=SHA, force=True)  # a directory
    assert sorted(p.name for p in tmp_path.iterdir()) == ["corrupt.h5", "other.h5", "results.h5"]


def test_read_only_target_is_refused_as_such(tmp_path):
    """A read-only results file (mode 0444; also when running as root, who could write it) ->
    OutputError "cannot write results to X: permission denied", even with force; file untouched."""
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    path.chmod(0o444)
    before = path.read_bytes()
    for force in (False, True):
        with pytest.raises(OutputError, match=r"cannot write results to .*results\.h5: permission denied"):
            check_target(path, config_sha256=SHA, force=force)
        with pytest.raises(OutputError, match="permission denied"):
            write_group(path, geometry_group(name="static"), config_toml=TOML, config_sha256=SHA, force=force)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5"]


def test_base_config_hash_is_recorded_and_accepted(tmp_path):
    """write_groups records base_config_sha256; check_target accepts a file of another configuration
    whose base is the given one (modal --rtol's re-run), and write_groups itself stays strict."""
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=OTHER_SHA)
    from beltdyn.results.io import write_groups

    write_groups(path, [geometry_group()], config_toml=TOML, config_sha256=OTHER_SHA, base_config_sha256=SHA)
    assert read_root_attrs(path)["base_config_sha256"] == SHA
    check_target(path, config_sha256=SHA, base_config_sha256=SHA)
    with pytest.raises(OutputError, match="different configuration"):
        check_target(path, config_sha256=SHA)
    with pytest.raises(OutputError, match="different configuration"):
        write_groups(path, [geometry_group()], config_toml=TOML, config_sha256=SHA, base_config_sha256=SHA)


def test_invalid_group_content_is_rejected_before_touching_files(tmp_path):
    """Complex data, inconsistent dimension sizes, repeated dims and wrong ndim raise ValueError
    and create no file."""
    path = tmp_path / "results.h5"
    bad = [
        lambda: (Variable(name="z", data=np.array([1 + 2j]), dims=("k",), units="1"),),
        lambda: (Variable(name="a", data=np.ones(2), dims=("k",), units="1"),
                 Variable(name="b", data=np.ones(3), dims=("k",), units="1")),
        lambda: (Variable(name="m", data=np.ones((2, 2)), dims=("k", "k"), units="1"),),
        lambda: (Variable(name="m", data=np.ones((2, 2)), dims=("k",), units="1"),),
        lambda: (Variable(name="m", data=np.ones(2), dims=("k",), units=""),),
        lambda: (Variable(name="m", data=np.array([{}]), dims=("k",), units="1"),),
    ]
    for make_variables in bad:
        with pytest.raises(ValueError):
            write_group(path, GroupData(name="static", coords={}, variables=make_variables()),
                        config_toml=TOML, config_sha256=SHA)
    with pytest.raises(ValueError):
        write_group(path, GroupData(name="static", coords={"k": [1.0, 2.0]},
                                    variables=(Variable(name="a", data=np.ones(3), dims=("k",), units="1"),)),
                    config_toml=TOML, config_sha256=SHA)
    with pytest.raises(ValueError):
        GroupData(name="static", coords={}, status="done")
    with pytest.raises(ValueError):
        Variable(name="a/b", data=np.ones(1), dims=("k",), units="1")
    assert list(tmp_path.iterdir()) == []


def test_read_errors_are_output_errors(tmp_path):
    """Reading a missing file or group raises OutputError naming the file."""
    path = tmp_path / "results.h5"
    with pytest.raises(OutputError, match="results.h5"):
        read_root_attrs(path)
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    with pytest.raises(OutputError, match="/modal"):
        read_group(path, "modal")


# ----------------------------------------------------------------------------------------------
# StreamWriter


def stream(path: Path, **kw) -> StreamWriter:
    args = dict(
        series={"q": ((3, 2), "m", ("node", "component")), "tension": ((), "N", ())},
        coords={"component": ["x", "y"]},
        coord_units={"node": "1"},
        variables=(Variable(name="mass", data=np.array([1.0, 2.0, 3.0]), dims=("node",), units="kg"),),
        attrs={"integrator": "HHT-alpha"},
        config_toml=TOML,
        config_sha256=SHA,
    )
    args.update(kw)
    return StreamWriter(path, "transient", **args)


def rows(t: np.ndarray) -> dict[str, np.ndarray]:
    q = np.sin(t)[:, None, None] * np.arange(6.0).reshape(1, 3, 2)
    return {"q": q, "tension": 100.0 + t}


def test_stream_writer_appends_10000_rows_growable_chunked(tmp_path):
    """10_000 rows appended in uneven chunks round-trip; the time axis is unlimited and chunked
    (a few hundred rows), `time` is the dimension scale of axis 0; status complete; xarray opens it."""
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    t_all = np.arange(10_000) * 1e-3
    sizes = [1, 7, 300, 1000, 2500, 13]
    with stream(path, flush_every=5) as w:
        i = k = 0
        while i < t_all.size:
            n = min(sizes[k % len(sizes)], t_all.size - i)
            w.append(t_all[i:i + n], rows(t_all[i:i + n]))
            i += n
            k += 1
        w.append(10.0, {"q": np.zeros((3, 2)), "tension": 0.5})  # scalar time: one row
        assert w.rows == 10_001
        w.set_attrs(n_steps=10_001, wall_time=1.5)

    t_exp = np.append(t_all, 10.0)
    check_contract(path)
    with h5py.File(path, "r") as f:
        g = f["transient"]
        assert g.attrs["status"] == "complete"
        assert "error" not in g.attrs
        for name in ("time", "q", "tension"):
            ds = g[name]
            assert ds.maxshape[0] is None
            assert ds.chunks is not None and 1 <= ds.chunks[0] <= 2048
        assert g["q"].chunks[0] <= 512
        assert g["q"].dims[0]["time"] == g["time"]
        assert g["time"].attrs["units"] == "s"
    out = read_group(path, "transient")
    np.testing.assert_array_equal(out["coords"]["time"], t_exp)
    expected = rows(t_all)
    np.testing.assert_array_equal(out["variables"]["q"][:-1], expected["q"])
    np.testing.assert_array_equal(out["variables"]["tension"], np.append(expected["tension"], 0.5))
    np.testing.assert_array_equal(out["variables"]["mass"], [1.0, 2.0, 3.0])
    assert out["dims"]["q"] == ("time", "node", "component")
    assert out["attrs"]["integrator"] == "HHT-alpha" and out["attrs"]["n_steps"] == 10_001
    assert "center" in read_group(path, "geometry")["variables"]  # other groups kept

    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    tree = xr.open_datatree(path, engine="h5netcdf")
    try:
        ds = tree["transient"].ds
        assert dict(ds.sizes) == {"time": 10_001, "node": 3, "component": 2}
        assert ds["q"].dims == ("time", "node", "component")
        assert ds["time"].attrs["units"] == "s"
        np.testing.assert_array_equal(ds["tension"].values[:5], expected["tension"][:5])
    finally:
        tree.close()


def test_stream_writer_exception_marks_failed_and_keeps_rows(tmp_path):
    """An exception inside the `with` block -> status failed, error = str(exc), all rows appended
    so far kept (including rows still buffered), the exception propagates, no temp file left."""
    path = tmp_path / "results.h5"
    t = np.arange(777) * 0.01
    with pytest.raises(RuntimeError, match="Newton diverged"):
        with stream(path) as w:
            w.append(t, rows(t))
            raise RuntimeError("Newton diverged at step 778")
    out = read_group(path, "transient")
    assert out["attrs"]["status"] == "failed"
    assert out["attrs"]["error"] == "Newton diverged at step 778"
    np.testing.assert_array_equal(out["coords"]["time"], t)
    np.testing.assert_array_equal(out["variables"]["tension"], rows(t)["tension"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5"]


def test_stream_writer_keyboard_interrupt_marks_interrupted(tmp_path):
    """KeyboardInterrupt inside the `with` block -> status interrupted, rows kept, re-raised."""
    path = tmp_path / "results.h5"
    t = np.arange(300) * 0.01
    with pytest.raises(KeyboardInterrupt):
        with stream(path) as w:
            w.append(t[:100], rows(t[:100]))
            w.append(t[100:], rows(t[100:]))
            raise KeyboardInterrupt
    out = read_group(path, "transient")
    assert out["attrs"]["status"] == "interrupted"
    assert out["variables"]["q"].shape == (300, 3, 2)


def test_stream_writer_running_group_is_visible_and_readable_until_close(tmp_path):
    """While the writer is open the file shows the group "running" with this process as its (live)
    writer; another process reads it without waiting (plain h5py, and read_group with the samples so
    far from the stream journal), the earlier groups unchanged; close makes it complete in the file,
    and leaves nothing beside it (small results: no parts folder, the journal and lock removed)."""
    path = tmp_path / "results.h5"
    write_group(path, geometry_group(), config_toml=TOML, config_sha256=SHA)
    w = stream(path, flush_every=1)
    t = np.arange(50) * 0.1
    w.append(t, rows(t))
    assert w.journal_path.is_file() and w.journal_path.parent.name == "results.h5.parts"
    code = ("import sys, os, h5py; from beltdyn.results.io import read_group, group_states\n"
            "f = h5py.File(sys.argv[1], 'r'); g = f['transient']\n"
            "assert g.attrs['status'] == 'running' and int(g.attrs['writer_pid']) == int(sys.argv[2])\n"
            "assert 'time' not in g and 'center' in f['geometry']\n"
            "out = read_group(sys.argv[1], 'transient')\n"
            "assert out['writer']['alive'] is True and out['variables']['q'].shape == (50, 3, 2), out['writer']\n"
            "assert out['dims']['q'] == ('time', 'node', 'component') and out['coords']['time'][-1] == 4.9\n"
            "s = group_states(sys.argv[1])['transient']\n"
            "assert s.status == 'running' and s.writer_alive is True and not s.orphaned and s.samples == 50\n")
    subprocess.run([sys.executable, "-c", code, str(path), str(os.getpid())], check=True, timeout=60)
    w.close("complete")
    w.close("failed")  # second close: no effect
    out = read_group(path, "transient")
    assert out["attrs"]["status"] == "complete" and "writer" not in out
    assert not set(out["attrs"]) & {"writer_pid", "writer_host", "writer_start", "stream_journal"}
    np.testing.assert_array_equal(out["coords"]["time"], t)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.h5"]
    with pytest.raises(RuntimeError):
        w.append(t, rows(t))


def test_stream_writer_subgroup_and_late_variables(tmp_path):
    """add_variables / add_subgroup write summaries at the end; /transient/spectrum shares the
    parent's coordinate values and the tree opens in xarray."""
    path = tmp_path / "results.h5"
    t = np.arange(64) / 64
    with stream(path) as w:
        w.append(t, rows(t))
        w.add_variables((Variable(name="rms", data=np.ones((3, 2)), dims=("node", "component"), units="m"),
                         Variable(name="peak", data=np.arange(4.0), dims=("probe",), units="N")),
                        coords={"probe": ["p0", "p1", "p2", "p3"]})
        w.add_subgroup(GroupData(
            name="spectrum", coords={"frequency": np.fft.rfftfreq(64, 1 / 64)}, coord_units={"frequency": "Hz"},
            variables=(Variable(name="amplitude_real", data=np.ones((33, 2)), dims=("frequency", "component"),
                                units="m"),
                       Variable(name="amplitude_imag", data=np.zeros((33, 2)), dims=("frequency", "component"),
                                units="m"))))
        with pytest.raises(ValueError):  # differs from the parent's "component" coordinate
            w.add_subgroup(GroupData(name="bad", coords={"component": ["u", "v"]}))
    check_contract(path)
    spec = read_group(path, "transient/spectrum")
    assert spec["coords"]["frequency"].shape == (33,)
    np.testing.assert_array_equal(spec["coords"]["component"], ["x", "y"])
    assert spec["units"]["frequency"] == "Hz"
    main = read_group(path, "transient")
    np.testing.assert_array_equal(main["coords"]["probe"], ["p0", "p1", "p2", "p3"])
    assert main["dims"]["rms"] == ("node", "component")

    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    tree = xr.open_datatree(path, engine="h5netcdf")
    try:
        sub = tree["transient/spectrum"].ds
        assert sub["amplitude_real"].dims == ("frequency", "component")
        assert sub["frequency"].attrs["units"] == "Hz"
    finally:
        tree.close()


def test_h5py_is_imported_lazily():
    """Importing beltdyn.results.io does not import h5py (CLI start-up time)."""
    code = "import sys, beltdyn.results.io; assert 'h5py' not in sys.modules, 'h5py imported'"
    root = Path(__file__).resolve().parents[1]
    subprocess.run([sys.executable, "-c", code], check=True, cwd=root)


# ----------------------------------------------------------------------------------------------
# Rewrites: a transaction's root holds only live objects


def modal_group(value: float) -> GroupData:
    """A modal-like group: its shapes (80 kB) stay in the root, or go to a part when INLINE_BYTES is 1 kB."""
    return GroupData(name="modal", coords={"mode": np.arange(1, 11)},
                     variables=(Variable(name="frequency", data=np.arange(10.0) + value, dims=("mode",), units="Hz"),
                                Variable(name="shape", data=np.full((10, 1000), value), dims=("mode", "dof"),
                                         units="1")))


def write_drive(path: Path, value: float) -> None:
    """Every kind of write on one file: /geometry (write_group), a streamed /transient with late variables
    and a subgroup /transient/spectrum (StreamWriter: two transactions), /modal; contents depend on `value`."""
    write_group(path, geometry_group(attrs={"tension": 100.0 + value}), config_toml=TOML, config_sha256=SHA)
    t = np.arange(600) * 1e-3
    with stream(path) as w:
        w.append(t, rows(t + value))
        w.add_variables((Variable(name="rms", data=np.full((3, 2), value), dims=("node", "component"), units="m"),))
        w.add_subgroup(GroupData(
            name="spectrum", coords={"frequency": np.arange(33.0)}, coord_units={"frequency": "Hz"},
            variables=(Variable(name="amplitude", data=np.full((33, 2), value), dims=("frequency", "component"),
                                units="m"),)))
    write_group(path, modal_group(value), config_toml=TOML, config_sha256=SHA)


_VOLATILE = {"created_utc", "modified_utc", "file_id", "parts"}  # times, the file id, part names (random tokens)


def _stored(aid) -> tuple:
    """An attribute's or dataset's stored type and shape, as comparable values."""
    return str(aid.dtype), repr(h5py.check_string_dtype(aid.dtype)), aid.shape


def file_content(path: Path) -> dict:
    """Everything a reader sees in a results file, by object path: link order, attributes with their stored
    types, datasets (type, shape, maxshape, chunks, values), virtual datasets (the dataset they map in an
    existing part of the file), dimension scales (the scales of each axis; the (dataset, axis) a scale
    labels, from its REFERENCE_LIST). Attributes in _VOLATILE are reduced to their number of values."""
    out = {}
    with h5py.File(path, "r") as f:
        def attrs(obj) -> dict:
            d = {}
            for key in obj.attrs:
                if key in ("DIMENSION_LIST", "REFERENCE_LIST"):
                    continue
                value = obj.attrs[key]
                value = np.size(value) if key in _VOLATILE else np.asarray(value).tolist()
                d[key] = (_stored(obj.attrs.get_id(key)), value)
            return d

        def visit(name, obj):
            if isinstance(obj, h5py.Group):
                out[name] = ("group", list(obj.keys()), attrs(obj))
                return
            entry = {"attrs": attrs(obj), "stored": _stored(obj), "maxshape": obj.maxshape, "chunks": obj.chunks,
                     "values": np.asarray(obj.asstr()[()] if h5py.check_string_dtype(obj.dtype) else obj[()]).tolist(),
                     "scales": [[s.name for s in obj.dims[i].values()] for i in range(obj.ndim)],
                     "virtual": obj.is_virtual}
            if obj.is_virtual:
                sources = obj.virtual_sources()
                assert all((path.parent / rwrite.source_file(s)).is_file() for s in sources), name
                entry["sources"] = [(s.dset_name, str(Path(s.file_name).parent)) for s in sources]
            if h5py.h5ds.is_scale(obj.id):
                labels = obj.attrs["REFERENCE_LIST"] if "REFERENCE_LIST" in obj.attrs else []
                entry["labels"] = sorted((f[ref].name, int(axis)) for ref, axis in labels)
            out[name] = entry

        out["/"] = ("root", list(f.keys()), attrs(f))
        f.visititems(visit)
    return out


@pytest.mark.parametrize("inline", [1 << 20, 1024], ids=["in-root", "in-parts"])
def test_a_file_rewritten_20_times_reads_back_identical_to_a_fresh_one(tmp_path, monkeypatch, inline):
    """Every group of a file replaced 20 times (80 transactions; StreamWriter's copy the running group in and
    change it) against the same content written once: the same links in the same order, attributes (values and
    stored types), datasets, virtual datasets resolving into the file's parts, dimension scales attached to the
    same axes (and each scale's back-references); read_group and xarray read the same. With 1 kB inline, every
    series, the `time` scale and /modal's shapes are virtual datasets. Compared exactly (the same numbers were
    written)."""
    monkeypatch.setattr(rwrite, "INLINE_BYTES", inline)
    fresh, rewritten = tmp_path / "a" / "r.h5", tmp_path / "b" / "r.h5"
    write_drive(fresh, 7.0)
    for value in [*range(19), 7.0]:
        write_drive(rewritten, float(value))
    a, b = file_content(fresh), file_content(rewritten)
    assert list(a) == list(b)
    for name in a:
        assert a[name] == b[name], name
    assert any(e["virtual"] for e in b.values() if isinstance(e, dict)) == (inline == 1024)
    assert any("labels" in e and e["virtual"] for e in b.values() if isinstance(e, dict)) == (inline == 1024)
    check_contract(rewritten)
    for group in ("geometry", "transient", "transient/spectrum", "modal"):
        ga, gb = read_group(fresh, group), read_group(rewritten, group)
        assert ga["dims"] == gb["dims"] and ga["units"] == gb["units"]
        for kind in ("coords", "variables"):
            assert list(ga[kind]) == list(gb[kind])
            for key in ga[kind]:
                np.testing.assert_array_equal(ga[kind][key], gb[kind][key])
    parts = sorted(p.name for p in rewritten.parent.rglob("*") if p.is_file())
    with h5py.File(rewritten, "r") as f:
        referenced = {Path(r).name for r in rwrite.references(f)}
    assert parts == sorted({"r.h5", *referenced})  # nothing left of the 79 replaced groups' parts
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    with xr.open_datatree(fresh, engine="h5netcdf") as ta, xr.open_datatree(rewritten, engine="h5netcdf") as tb:
        xr.testing.assert_equal(ta, tb)


@pytest.mark.parametrize("inline", [1 << 20, 1024], ids=["in-root", "in-parts"])
def test_replacing_groups_20_times_keeps_the_root_no_larger_than_a_fresh_one(tmp_path, monkeypatch, inline):
    """The root after each of 20 rewrites of every group (then of /modal alone, 20 times) is at most the size
    of a fresh file with the same content (written once) + 1 %, and the same after every rewrite within 1 %:
    a transaction that replaces a group copies only the live objects into a fresh root, so nothing of a
    replaced group stays. (The fresh file is the larger, by 11 % in the root and 76 % in parts: its additions
    were made in byte copies, which keep HDF5's slack of the writes; a rebuilt root drops it. Measured: every
    rewrite the same to the byte.) Before, every replaced group stayed in the root as garbage that each later
    write copied again: the first rewrite added 24 kB (in parts) and 78 kB (in the root), and the root grew
    with every one."""
    monkeypatch.setattr(rwrite, "INLINE_BYTES", inline)
    fresh, rewritten = tmp_path / "a" / "r.h5", tmp_path / "b" / "r.h5"
    write_drive(fresh, 7.0)
    write_drive(rewritten, -1.0)
    sizes = []
    for value in range(20):
        write_drive(rewritten, float(value))
        sizes.append(rewritten.stat().st_size)
    for value in range(20):
        write_group(rewritten, modal_group(float(value)), config_toml=TOML, config_sha256=SHA)
        sizes.append(rewritten.stat().st_size)
    assert max(sizes) <= 1.01 * fresh.stat().st_size, (sizes, fresh.stat().st_size)
    assert max(sizes) - min(sizes) <= 0.01 * min(sizes), sizes
