"""Copying the live content of one results root into a fresh one (what a `results_write.Transaction`
carries over): attributes with their stored types, and top-level groups with everything below them.

A group is copied by HDF5 itself (H5Ocopy: data, attributes, subgroups, and virtual datasets, whose part
files stay named relative to the root's folder). One thing H5Ocopy gets wrong between files is the
object references in the attributes of dimension scales (HDF5 2.0, also with its expand-references
flag): DIMENSION_LIST (on a dataset: the scales of each axis, a variable-length array of references
per axis) and REFERENCE_LIST (on a scale: the (dataset, axis) records it labels) keep the addresses of
the old file. `copy_group` rewrites them, mapping old addresses to paths and paths to new addresses
with one H5Ovisit of each tree; no object of the old tree is opened.

Why not `Dimension.attach_scale` on the copy: HDF5's dimension-scale API asks each dataset for its
extent, and a virtual dataset of unlimited extent (a streamed series) answers by opening its part
files with the intent of the root, read-write: the part's mtime changes, although a committed part is
never to be modified. Why not a byte copy of the root: HDF5 never reclaims the space of a deleted
object, so a replaced group would stay in it as garbage, copied again by every later write.

The references are assumed to stay within one top-level group (every dataset's scales are
coordinates of its own group; the schema has no other case); one to an object outside the copied
group is dropped.
"""

from __future__ import annotations

import numpy as np

from beltdyn.errors import OutputError
from beltdyn.results.schema import h5py_module

_LABELS = b"REFERENCE_LIST"
_SCALES = b"DIMENSION_LIST"


def _attr_value(aid):
    """(value, memory type) of the open attribute `aid` as stored (vlen strings as bytes, references as
    h5py References); value None for an empty (null dataspace) attribute. h5py's low-level API: its
    `attrs` costs ~0.1 ms an attribute."""
    h5py = h5py_module()
    dtype = aid.dtype
    htype = h5py.h5t.py_create(dtype)
    if aid.shape is None:
        return None, htype
    shape = aid.shape
    if dtype.subdtype is not None:  # an HDF5 array type: numpy wants its dims in the shape
        dtype, sub = dtype.subdtype
        shape = shape + sub
    value = np.zeros(shape, dtype=dtype)
    aid.read(value, mtype=htype)
    return value, htype


def copy_attrs(src, dst) -> None:
    """Every attribute of the open HDF5 object `src` created on `dst` with its stored type and dataspace."""
    h5py = h5py_module()
    for index in range(h5py.h5a.get_num_attrs(src.id)):
        aid = h5py.h5a.open(src.id, index=index)
        value, htype = _attr_value(aid)
        new = h5py.h5a.create(dst.id, aid.name, aid.get_type(), aid.get_space())
        if value is not None:
            new.write(value, mtype=htype)


def _tree(f, top: bytes) -> tuple[dict[bytes, int], list[bytes]]:
    """Of the object `top` of the open file `f` and everything below it: {path: address}, and the paths
    of the datasets that have attributes. One H5Ovisit; no object opened."""
    h5py = h5py_module()
    addrs: dict[bytes, int] = {}
    datasets: list[bytes] = []

    def visit(rel: bytes, info) -> None:
        path = top if rel == b"." else top + b"/" + rel
        addrs[path] = info.addr
        if info.type == h5py.h5o.TYPE_DATASET and info.num_attrs:
            datasets.append(path)

    h5py.h5o.visit(f.id, visit, obj_name=top, info=True)
    return addrs, datasets


def _raw_labels_dtype(ftype) -> np.dtype:
    """The numpy layout of a REFERENCE_LIST record read without conversion: the object reference as the
    8-byte little-endian address HDF5 stores (H5T_STD_REF_OBJ), then the axis."""
    h5py = h5py_module()
    n = ftype.get_nmembers() if ftype.get_class() == h5py.h5t.COMPOUND else 0
    ref = ftype.get_member_type(0) if n == 2 else None
    if ref is None or ref.get_class() != h5py.h5t.REFERENCE or ref.get_size() != 8:
        raise OutputError("this HDF5 stores dimension-scale references in an unknown form; cannot copy results "
                          "groups with it")
    return np.dtype({"names": ["dataset", "axis"], "formats": ["<u8", ftype.get_member_type(1).dtype],
                     "offsets": [ftype.get_member_offset(0), ftype.get_member_offset(1)],
                     "itemsize": ftype.get_size()})


def _write(obj, key: bytes, value: np.ndarray, ftype, mtype) -> None:
    """Overwrite attribute `key` of the open object `obj` by `value` (removed when empty, as HDF5's
    dimension-scale API does)."""
    h5py = h5py_module()
    aid = h5py.h5a.open(obj, key)
    if value.shape == aid.shape:
        aid.write(value, mtype=mtype)
        return
    del aid
    h5py.h5a.delete(obj, key)
    if value.size:
        h5py.h5a.create(obj, key, ftype, h5py.h5s.create_simple(value.shape)).write(value, mtype=mtype)


def copy_group(old, new, name: str) -> None:
    """Copy top-level object `name` of the open file `old` into the open file `new` (see the module
    docstring), its dimension scales attached as they were."""
    h5py = h5py_module()
    top = b"/" + name.encode()
    h5py.h5o.copy(old.id, top, new.id, top)
    new_addrs, datasets = _tree(new, top)
    opened = [(path, h5py.h5o.open(new.id, path)) for path in datasets]
    scales = [(path, obj) for path, obj in opened if h5py.h5a.exists(obj, _LABELS)]
    labelled = [(path, obj) for path, obj in opened if h5py.h5a.exists(obj, _SCALES)]
    if not scales and not labelled:
        return
    path_at = {addr: path for path, addr in _tree(old, top)[0].items()}
    axes: dict[bytes, dict[int, list[bytes]]] = {}  # dataset -> axis -> its scales (paths)
    raw = None
    for scale, obj in scales:  # REFERENCE_LIST: read (from the copy: the old addresses) and written as stored
        aid = h5py.h5a.open(obj, _LABELS)
        ftype = aid.get_type()
        if raw is None:  # (the same type for every scale)
            raw = _raw_labels_dtype(ftype)
        records = np.zeros(aid.shape, dtype=raw)
        aid.read(records, mtype=ftype)
        del aid
        targets = [path_at.get(int(a)) for a in records["dataset"]]
        records = records[np.array([t is not None for t in targets], dtype=bool)]
        targets = [t for t in targets if t is not None]
        records["dataset"] = [new_addrs[t] for t in targets]
        for target, axis in zip(targets, records["axis"]):
            axes.setdefault(target, {}).setdefault(int(axis), []).append(scale)
        _write(obj, _LABELS, records, ftype, ftype)
    refs: dict[bytes, object] = {}
    mtype = None
    for dataset, obj in labelled:  # DIMENSION_LIST: rebuilt from the scales' records (one per axis in the schema)
        aid = h5py.h5a.open(obj, _SCALES)
        ftype, rank = aid.get_type(), aid.shape[0]
        if mtype is None:  # (the same type for every dataset)
            mtype = h5py.h5t.py_create(aid.dtype)
        del aid
        value = np.empty(rank, dtype=object)
        for axis in range(rank):
            paths = axes.get(dataset, {}).get(axis, [])
            for p in paths:
                if p not in refs:
                    refs[p] = h5py.h5r.create(new.id, p, h5py.h5r.OBJECT)
            value[axis] = np.array([refs[p] for p in paths], dtype=object)
        _write(obj, _SCALES, value if any(len(v) for v in value) else value[:0], ftype, mtype)
