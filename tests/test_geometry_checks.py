"""The lean `compute_layout` (span ends laid out together, the checks screened in one pass by `_path_ok`)
against the straightforward layout it replaced: on random drives, failing ones and ones placed on the
checks' thresholds, the same arrays bit for bit (shapes and dtypes too) or the same GeometryError
(message and key). The reference below is the layout as it was written before, its checks the module's
own one-by-one checks (`_check_apart`, `_check_tangents`, `_check_path`) in their order."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

from beltdyn.model.geometry import (TWO_PI, GeometryError, Layout, _check_apart, _check_path, _check_tangents,
                              compute_layout)

FIELDS = ("center", "radius", "side_sign", "span_start", "span_end", "span_length", "span_angle", "start_normal",
          "end_normal", "wrap_angle", "arc_length")


def reference_orientation(center: np.ndarray) -> int:
    x, y = center[:, 0], center[:, 1]
    nxt = np.arange(1, len(x) + 1) % len(x)
    area2 = float(np.dot(x, y[nxt]) - np.dot(x[nxt], y))
    scale = float((center.max(axis=0) - center.min(axis=0)).max()) ** 2
    return -1 if area2 < -1e-12 * max(scale, 1e-300) else 1


def reference_layout(center, radius, side_sign, names, *, orientation=None, check=True) -> Layout:
    """compute_layout before the lean version: every array on its own, the checks one by one."""
    center = np.asarray(center, dtype=float)
    radius = np.asarray(radius, dtype=float)
    side_sign = np.asarray(side_sign, dtype=float)
    n = len(radius)
    o = reference_orientation(center) if orientation is None else orientation
    if check:
        _check_apart(center, radius, names)
    nxt, prv = np.roll(np.arange(n), -1), np.roll(np.arange(n), 1)
    rho = o * side_sign * radius
    d = center[nxt] - center
    dist = np.hypot(d[:, 0], d[:, 1])
    drho = rho - rho[nxt]
    q = drho / dist
    if check:
        _check_tangents(q, names)
    alpha = np.arctan2(d[:, 1], d[:, 0]) + np.arcsin(np.minimum(np.maximum(q, -1.0), 1.0))
    m = np.empty((n, 2))
    m[:, 0] = np.sin(alpha)
    m[:, 1] = -np.cos(alpha)
    length = np.sqrt(np.maximum(dist * dist - drho * drho, 0.0))
    wrap = np.mod((o * side_sign) * (alpha - alpha[prv]), TWO_PI)
    arc = radius * wrap
    lay = Layout(
        names=tuple(names), center=center, radius=radius, side_sign=side_sign, orientation=o,
        span_start=center + rho[:, None] * m, span_end=center[nxt] + rho[nxt][:, None] * m, span_length=length,
        span_angle=alpha, start_normal=np.sign(rho)[:, None] * m, end_normal=np.sign(rho[nxt])[:, None] * m,
        wrap_angle=wrap, arc_length=arc, belt_length=float(length.sum() + arc.sum()),
    )
    if check:
        _check_path(lay)
    return lay


def outcome(f, *args, **kw):
    """The layout's fields, or the error's (message, key)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore" if kw.get("check") is False else "error")  # no warning on a checked call
            lay = f(*args, **kw)
    except GeometryError as exc:
        return ("error", str(exc), exc.key)
    return ("layout", lay)


def assert_same(got, want):
    assert got[0] == want[0], (got, want)
    if got[0] == "error":
        assert got[1:] == want[1:]
        return
    a, b = got[1], want[1]
    assert set(vars(a)) == {f.name for f in dataclasses.fields(Layout)}  # every field, nothing else
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and x.dtype == y.dtype, name
        np.testing.assert_array_equal(x, y, err_msg=name)  # bit for bit (NaN where both are)
    assert (a.names, a.orientation, a.belt_length) == (b.names, b.orientation, b.belt_length) or (
        math.isnan(a.belt_length) and math.isnan(b.belt_length))


def compare(center, radius, side, orientation=None, check=True):
    names = tuple(f"p{i}" for i in range(len(radius)))
    args = (np.asarray(center, float), np.asarray(radius, float), np.asarray(side, float), names)
    assert_same(outcome(compute_layout, *args, orientation=orientation, check=check),
                outcome(reference_layout, *args, orientation=orientation, check=check))


def ring(rng, n):
    """n pulleys on a ring (a drive that mostly passes), some backside, jittered."""
    angles = np.sort(rng.uniform(0, TWO_PI, n))
    c = rng.uniform(0.3, 1.5) * np.column_stack([np.cos(angles), np.sin(angles)]) + rng.normal(0, 0.05, (n, 2))
    return c, rng.uniform(0.02, 0.2, n), np.where(rng.random(n) < 0.8, 1.0, -1.0)


@pytest.mark.parametrize("seed", range(4))
def test_random_drives_as_the_reference(seed):
    # Random boxes of pulleys (most fail a check: overlap, no tangent, not wrapped, winding, a cut), rings
    # (most pass), reversed, either orientation given or computed, checked and unchecked.
    rng = np.random.default_rng(seed)
    for _ in range(150):
        n = int(rng.integers(2, 9))
        if rng.random() < 0.5:
            c, r, side = rng.uniform(0, 1, (n, 2)), rng.uniform(0.01, 0.25, n), np.where(rng.random(n) < 0.7, 1.0, -1.0)
        else:
            c, r, side = ring(rng, n)
        if rng.random() < 0.3:
            c, r, side = c[::-1], r[::-1], side[::-1]  # also a strided (not contiguous) centre array
        o = [None, 1, -1][int(rng.integers(3))]
        compare(c, r, side, orientation=o)
        compare(c, r, side, orientation=o, check=False)


def gaps(lay: Layout) -> tuple[np.ndarray, np.ndarray]:
    """The checks' gaps in the reference's arithmetic: (n, n) between centres less pulley i's radius
    (row i < column k, else inf), and of every centre from every other span's segment (row: span)."""
    n, c = lay.n, lay.center
    apart = np.full((n, n), np.inf)
    cut = np.full((n, n), np.inf)
    for i in range(n):
        a, ab = lay.span_start[i], lay.span_end[i] - lay.span_start[i]
        for k in range(n):
            if k > i:
                apart[i, k] = float(np.hypot(*(c[i] - c[k]))) - lay.radius[i]
            if k not in (i, (i + 1) % n):
                rv = c[k] - a
                t = min(max((rv[0] * ab[0] + rv[1] * ab[1]) / max(ab[0] * ab[0] + ab[1] * ab[1], 1e-300), 0.0), 1.0)
                cut[i, k] = float(np.hypot(rv[0] - t * ab[0], rv[1] - t * ab[1]))
    return apart, cut


def kind(result) -> str:
    return result[0] if result[0] == "layout" else next(
        (w for w in ("overlap", "cuts", "tangent", "wrap", "winds") if w in result[1]), result[1])


def across(c, r, side, k: int, edge: float, orientation: int) -> list[str]:
    """Pulley k's radius at edge, give or take two ulps: the outcomes, each compared with the reference's."""
    names = tuple(f"p{i}" for i in range(len(r)))
    kinds = []
    for ulps in range(-2, 3):
        rr = np.array(r, float)
        rr[k] = edge + ulps * math.ulp(edge)
        got = outcome(compute_layout, c, rr, side, names, orientation=orientation)
        assert_same(got, outcome(reference_layout, c, rr, side, names, orientation=orientation))
        kinds.append(kind(got))
    return kinds


@pytest.mark.parametrize("seed", range(3))
def test_overlap_threshold_as_the_reference(seed):
    # On rings that pass, the pulley nearest to touching another grown until the gap (distance less
    # both radii, the reference's arithmetic) is 0, give or take two ulps: the screen decides these
    # exactly as the checks; the outcome flips inside the window on some drives.
    rng = np.random.default_rng(100 + seed)
    flips = tried = 0
    while tried < 30:
        n = int(rng.integers(3, 8))
        c, r, side = ring(rng, n)
        try:
            lay = reference_layout(c, r, side, tuple(f"p{i}" for i in range(n)))
        except GeometryError:
            continue
        tried += 1
        apart, _ = gaps(lay)
        i, k = np.unravel_index(int(np.argmin(apart - r)), apart.shape)
        flips += len(set(across(c, r, side, k, apart[i, k], lay.orientation))) > 1
    assert flips > 0


@pytest.mark.parametrize("seed", range(3))
def test_cut_threshold_as_the_reference(seed):
    # A triangle A, B, C and a fourth pulley D (inside or backside) just above span A-B: D's radius set
    # to its distance from that span's segment + 1e-12 (the cut test's gap at -1e-12), give or take two
    # ulps: the screen decides these exactly as the checks; the outcome flips inside the window.
    rng = np.random.default_rng(200 + seed)
    flips = tried = 0
    while tried < 30:
        r = np.concatenate([rng.uniform(0.05, 0.15, 3), [rng.uniform(0.01, 0.04)]])
        c = np.array([[0.0, 0.0], [1.0, 0.0], [rng.uniform(0.3, 0.7), rng.uniform(0.4, 0.9)],
                      [rng.uniform(0.2, 0.8), rng.uniform(0.0, 0.15) + r[3] - min(r[0], r[1])]])
        side = np.array([1.0, 1.0, 1.0, rng.choice([1.0, -1.0])])
        try:
            lay = reference_layout(c, r, side, tuple("abcd"))
        except GeometryError:
            continue
        tried += 1
        flips += len(set(across(c, r, side, 3, gaps(lay)[1][0, 3] + 1e-12, lay.orientation))) > 1
    assert flips > 0


def test_unwrapped_pulley_as_the_reference():
    # Three equal pulleys in a row: the belt runs straight past the middle one (wrap 0).
    compare([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]], [0.1, 0.1, 0.1], [1.0, 1.0, 1.0])
    compare([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]], [0.1, 0.1, 0.1], [1.0, 1.0, 1.0], check=False)


def test_touching_pulleys_on_opposite_sides_as_the_reference():
    # Adjacent pulleys on opposite sides that touch: the gap is 0 (apart), the crossed tangent q = +-1
    # (no tangent line), and a hair's width either way.
    for d in (0.25, 0.25 + 2 ** -50, 0.25 - 2 ** -50):
        compare([[0.0, 0.0], [d, 0.0], [0.1, 0.8]], [0.15, 0.1, 0.1], [1.0, -1.0, 1.0])


def test_coincident_centres_raise_the_overlap_without_a_warning():
    names = ("a", "b", "c")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(GeometryError) as err:
            compute_layout(np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0]]), np.full(3, 0.1), np.ones(3), names)
    assert err.value.key == "pulleys[1].center"


