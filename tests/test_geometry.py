"""Belt geometry: the paper bench, closed forms, a hand-computed backside idler, random layouts."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from beltdyn.config import load_config
from beltdyn.model.geometry import GeometryError, compute_layout, fit_adjustable, layout_from_config

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def test_paper_bench_geometry():
    # Against DESIGN section 2 (independent re-computation of paper Eqs. 18-19): X_A = 0.2250477 m
    # (1e-7 m), spans 0.6715523 m (1e-7 m), wraps 169.0952 / 190.9048 deg (1e-4 deg), L = L0 (1e-12 m).
    cfg = load_config(CONFIGS / "paper" / "bench_T200.toml")
    lay = layout_from_config(cfg)
    assert lay.center[0, 0] == pytest.approx(0.2250477, abs=1e-7)
    assert lay.center[0, 1] == 0.0
    np.testing.assert_allclose(lay.span_length, 0.6715523, atol=1e-7)
    np.testing.assert_allclose(np.degrees(lay.wrap_angle), [169.0952, 190.9048], atol=1e-4)
    assert abs(lay.belt_length - cfg.belt.length) <= 1e-12
    # lower span horizontal, upper span inclined 10.9048 deg (DESIGN section 2)
    assert np.degrees(lay.span_angle[0]) == pytest.approx(0.0, abs=1e-9)
    assert abs(np.degrees(lay.span_angle[1])) == pytest.approx(180 - 10.9048, abs=1e-4)


@pytest.mark.parametrize("r,C", [(0.05, 0.3), (0.1, 1.0), (0.3, 0.61)])
def test_two_equal_pulleys_closed_form(r, C):
    # Closed form: L = 2 C + 2 pi r, both wraps pi (relative 1e-14).
    lay = compute_layout(np.array([[0.0, 0.0], [C, 0.0]]), np.array([r, r]), np.array([1.0, 1.0]), ("a", "b"))
    assert lay.belt_length == pytest.approx(2 * C + 2 * math.pi * r, rel=1e-14)
    np.testing.assert_allclose(lay.wrap_angle, math.pi, rtol=1e-14)
    np.testing.assert_allclose(lay.span_length, C, rtol=1e-14)


def test_two_unequal_pulleys_closed_form():
    # Open-belt closed form: L = 2 sqrt(C^2 - (R-r)^2) + pi (R + r) + 2 (R - r) asin((R - r)/C).
    R, r, C = 0.2, 0.05, 0.8
    lay = compute_layout(np.array([[0.0, 0.0], [C, 0.0]]), np.array([R, r]), np.array([1.0, 1.0]), ("a", "b"))
    expect = 2 * math.sqrt(C**2 - (R - r) ** 2) + math.pi * (R + r) + 2 * (R - r) * math.asin((R - r) / C)
    assert lay.belt_length == pytest.approx(expect, rel=1e-14)


def test_backside_idler_hand_computation():
    # Hand computation: A (0,0) r=0.1 and C (1,0) r=0.1 inside, idler B (0.5, 0.09) r=0.05 on the backside
    # pushes the upper span down. Crossed tangent A-B: D = |c_B - c_A|, length sqrt(D^2 - (rA + rB)^2),
    # its slope below horizontal g = asin((rA + rB)/D) - atan(0.09/0.5). Wrap on B = 2 g, on A and C pi + g.
    rA, rB = 0.1, 0.05
    c = np.array([[0.0, 0.0], [0.5, 0.09], [1.0, 0.0]])
    lay = compute_layout(c, np.array([rA, rB, rA]), np.array([1.0, -1.0, 1.0]), ("A", "B", "C"))
    D = math.hypot(0.5, 0.09)
    g = math.asin((rA + rB) / D) - math.atan2(0.09, 0.5)
    tangent = math.sqrt(D**2 - (rA + rB) ** 2)
    assert lay.orientation == -1
    np.testing.assert_allclose(lay.span_length, [tangent, tangent, 1.0], rtol=1e-13)
    np.testing.assert_allclose(lay.wrap_angle, [math.pi + g, 2 * g, math.pi + g], rtol=1e-13)
    expect = 1.0 + 2 * tangent + 2 * rA * (math.pi + g) + rB * 2 * g
    assert lay.belt_length == pytest.approx(expect, rel=1e-14)
    np.testing.assert_allclose(lay.span_start[0], [rA * math.sin(g), rA * math.cos(g)], atol=1e-14)


def test_fit_moves_adjustable_pulley_until_length_matches():
    # Newton (paper Eqs. 18-19): the fitted length equals L0 to 1e-13 relative, from either side.
    c = np.array([[0.0, 0.0], [0.7, 0.1]])
    for L0 in (1.8, 2.2):
        lay = fit_adjustable(c, np.array([0.05, 0.12]), np.array([1.0, 1.0]), ("a", "b"), index=1,
                             direction=np.array([1.0, 0.0]), target_length=L0)
        assert lay.belt_length == pytest.approx(L0, rel=1e-13)


def test_fit_starts_from_a_drawn_centre_that_does_not_fit():
    # The drawn centre of the adjustable pulley is only where the fit starts: drawn overlapping its
    # neighbour, it is moved out along its slide to the length L0 (1e-13 relative), and the fitted
    # layout passes every check (compute_layout with checks on the fitted centres gives the same path).
    c = np.array([[0.0, 0.0], [0.1, 0.0]])
    r, side = np.array([0.05, 0.12]), np.array([1.0, 1.0])
    lay = fit_adjustable(c, r, side, ("a", "b"), index=1, direction=np.array([1.0, 0.0]), target_length=2.2)
    assert lay.belt_length == pytest.approx(2.2, rel=1e-13)
    again = compute_layout(lay.center, r, side, ("a", "b"))
    np.testing.assert_array_equal(again.span_length, lay.span_length)


def test_fit_reports_unreachable_length():
    c = np.array([[0.0, 0.0], [0.7, 0.0]])
    with pytest.raises(GeometryError, match="too short") as err:
        fit_adjustable(c, np.array([0.05, 0.12]), np.array([1.0, 1.0]), ("a", "b"), index=1,
                       direction=np.array([1.0, 0.0]), target_length=0.5)
    assert err.value.key == "belt.length"
    with pytest.raises(GeometryError, match="too long"):
        fit_adjustable(c, np.array([0.05, 0.12]), np.array([1.0, 1.0]), ("a", "b"), index=1,
                       direction=np.array([1.0, 0.0]), target_length=3.0, slide_range=(-0.1, 0.1))


def _independent_checks(lay):
    """Recompute from tangent points alone: tangency, arc angles from the normals, closure."""
    n = lay.n
    t = lay.span_direction
    for i in range(n):
        j = (i + 1) % n
        chord = lay.span_end[i] - lay.span_start[i]
        assert np.linalg.norm(chord) == pytest.approx(lay.span_length[i], rel=1e-10, abs=1e-12)
        for p, k in ((lay.span_start[i], i), (lay.span_end[i], j)):
            radial = p - lay.center[k]
            assert np.linalg.norm(radial) == pytest.approx(lay.radius[k], rel=1e-10)
            assert abs(radial @ t[i]) <= 1e-10 * lay.radius[k]  # tangent line is perpendicular to the radius
    length = float(np.sum(np.linalg.norm(lay.span_end - lay.span_start, axis=1)))
    for k in range(n):
        a = lay.span_end[(k - 1) % n] - lay.center[k]
        b = lay.span_start[k] - lay.center[k]
        turn = math.atan2(a[0] * b[1] - a[1] * b[0], a @ b)  # signed angle from arrival to departure point
        sense = lay.orientation * lay.side_sign[k]
        arc = (sense * turn) % (2 * math.pi)
        length += lay.radius[k] * arc
    return length


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(min_value=2, max_value=6),
    data=st.data(),
)
def test_random_convex_layouts(n, data):
    # Property: belt length = sum of spans + arcs (recomputed independently from the tangent points),
    # signed wrap angles sum to 2 pi (one loop), every span is tangent to both of its pulleys.
    angles = sorted(data.draw(st.lists(st.floats(0, 2 * math.pi), min_size=n, max_size=n, unique=True)))
    assume(all(b - a > 0.3 for a, b in zip(angles, angles[1:])) and 2 * math.pi - angles[-1] + angles[0] > 0.3)
    radius_ring = data.draw(st.floats(0.3, 2.0))
    c = radius_ring * np.column_stack([np.cos(angles), np.sin(angles)])
    r = np.array(data.draw(st.lists(st.floats(0.01, 0.12), min_size=n, max_size=n))) * radius_ring
    if data.draw(st.booleans()):
        c = c[::-1].copy()
        r = r[::-1].copy()
    try:
        lay = compute_layout(c, r, np.ones(n), tuple(f"p{i}" for i in range(n)))
    except GeometryError:
        assume(False)
    assert lay.belt_length == pytest.approx(_independent_checks(lay), rel=1e-12)
    assert float(np.sum(lay.signed_wrap)) == pytest.approx(lay.orientation * 2 * math.pi, abs=1e-12)


@settings(max_examples=40, deadline=None)
@given(dx=st.floats(-0.2, 0.2), depth=st.floats(0.005, 0.08), ri=st.floats(0.01, 0.05), flip=st.booleans())
def test_random_backside_idlers(dx, depth, ri, flip):
    # Property on layouts with a backside idler pushed into the upper span: same identities as above.
    c = np.array([[0.0, 0.0], [0.5 + dx, 0.1 + ri - depth], [1.0, 0.0]])
    r = np.array([0.1, ri, 0.1])
    side = np.array([1.0, -1.0, 1.0])
    if flip:
        c, r, side = c[::-1].copy(), r[::-1].copy(), side[::-1].copy()
    try:
        lay = compute_layout(c, r, side, ("a", "b", "c"))
    except GeometryError:
        assume(False)
    assert lay.belt_length == pytest.approx(_independent_checks(lay), rel=1e-12)
    assert float(np.sum(lay.signed_wrap)) == pytest.approx(lay.orientation * 2 * math.pi, abs=1e-12)
    assert lay.wrap_angle[1 if not flip else 1] < math.pi


@pytest.mark.parametrize(
    "c,r,side,key",
    [
        ([[0, 0], [0.15, 0]], [0.1, 0.1], [1, 1], "pulleys[1].center"),  # overlap
        ([[0, 0], [0.5, 0.0], [1, 0]], [0.1, 0.05, 0.1], [1, 1, 1], "pulleys"),  # collinear, middle one smaller: winds twice
        ([[0, 0], [1, 0], [0.5, 0.3], [0.5, 0.05]], [0.1, 0.1, 0.05, 0.02], [1, 1, 1, 1], None),
    ],
)
def test_infeasible_layouts_raise(c, r, side, key):
    with pytest.raises(GeometryError) as err:
        compute_layout(np.array(c, float), np.array(r, float), np.array(side, float), tuple("abcd"[: len(r)]))
    if key:
        assert err.value.key == key


