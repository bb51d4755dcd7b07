"""Belt path geometry: tangent lines, spans, wrap angles, belt length, and the L0 fit.

Pure functions on numpy arrays (the tangent lines on floats: `span_lines`). Conventions: x right,
y up, angles counter-clockwise from +x. Pulleys are listed in belt order; span i runs from pulley i to
pulley (i+1) mod n. The loop runs counter-clockwise (orientation o = +1) when the polygon of pulley
centres is counter-clockwise or degenerate (two pulleys), clockwise (o = -1) otherwise. A pulley
wrapped on the inside of the loop turns the belt in the loop's sense, a backside pulley in the opposite
sense. With the signed radius rho = o * sigma * r (sigma = +1 inside, -1 backside) the tangent line of
span i has direction t = (cos a, sin a) and right normal m = (sin a, -cos a) with

    sin(a - b) = (rho_i - rho_{i+1}) / D,   d = c_{i+1} - c_i = D (cos b, sin b),

tangent points c_i + rho_i m and c_{i+1} + rho_{i+1} m, span length sqrt(D^2 - (rho_i - rho_{i+1})^2).
The belt length (paper Eq. 19, generalized) is the sum of span lengths and arc lengths r_j * wrap_j;
its gradient with respect to the centre of pulley j is t_in - t_out (arriving minus departing span
direction), which drives the Newton fit of the adjustable pulley (paper Eqs. 18-19).
"""

from __future__ import annotations

import cmath
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from beltdyn.config import DriveConfig
from beltdyn.errors import ConfigError
from beltdyn.model.angles import TWO_PI, pivot_angle, unwrap_near, wrap_angle


@dataclass(frozen=True, kw_only=True)
class Layout:
    """The belt path. Shapes: n pulleys, n spans (span i: pulley i -> pulley i+1)."""

    names: tuple[str, ...]
    center: np.ndarray  # (n, 2) m, solved centres
    radius: np.ndarray  # (n,) m
    side_sign: np.ndarray  # (n,) +1 inside, -1 backside
    orientation: int  # +1 counter-clockwise loop, -1 clockwise
    span_start: np.ndarray  # (n, 2) tangent point on pulley i, m
    span_end: np.ndarray  # (n, 2) tangent point on pulley i+1, m
    span_length: np.ndarray  # (n,) m
    span_angle: np.ndarray  # (n,) direction of travel, rad
    start_normal: np.ndarray  # (n, 2) outward unit normal of pulley i at span_start
    end_normal: np.ndarray  # (n, 2) outward unit normal of pulley i+1 at span_end
    wrap_angle: np.ndarray  # (n,) rad, >= 0
    arc_length: np.ndarray  # (n,) m
    belt_length: float  # m
    adjust_offset: float = 0.0  # m, travel of the adjustable pulley along its slide from its given centre
    adjust_index: int | None = None
    adjust_kind: str = "slide"  # "slide": adjust_offset in m along the slide; "arm": the angle (rad) the arm turned

    @property
    def n(self) -> int:
        return len(self.names)

    @property
    def span_direction(self) -> np.ndarray:
        """(n, 2) unit vectors of travel along each span."""
        return directions(self.span_angle)

    @property
    def signed_wrap(self) -> np.ndarray:
        """(n,) turning angle of the belt at each pulley, counter-clockwise positive."""
        return self.orientation * self.side_sign * self.wrap_angle

    def span_name(self, i: int) -> str:
        return f"{self.names[i]}-{self.names[(i + 1) % self.n]}"


def directions(angle: np.ndarray) -> np.ndarray:
    """(n, 2) the unit vectors (cos a, sin a) of angles a (n,)."""
    out = np.empty((len(angle), 2))
    out[:, 0] = np.cos(angle)
    out[:, 1] = np.sin(angle)
    return out


@dataclass(frozen=True, kw_only=True)
class BeltPath:
    """The belt path of pulleys at given centres without its tangent points: the spans and wraps an
    iterate of the L0 fit or of a tensioner arm's balance evaluates (`belt_path`, unchecked; the same
    numbers as the `Layout` that `compute_layout(check=False)` gives). Shapes: n pulleys, n spans."""

    span_angle: np.ndarray  # (n,) direction of travel, rad
    span_length: np.ndarray  # (n,) m
    arc_length: np.ndarray  # (n,) m
    belt_length: float  # m

    @property
    def n(self) -> int:
        return len(self.span_angle)

    @property
    def span_direction(self) -> np.ndarray:
        """(n, 2) unit vectors of travel along each span."""
        return directions(self.span_angle)


class GeometryError(ValueError):
    """An infeasible layout; `key` is the config key path at fault."""

    def __init__(self, message: str, key: str) -> None:
        super().__init__(message)
        self.key = key


def loop_orientation(center: np.ndarray) -> int:
    """+1 if the polygon of centres is counter-clockwise or degenerate, -1 if clockwise."""
    x, y = center[:, 0], center[:, 1]
    nxt = _next(len(x))
    area2 = float(np.dot(x, y[nxt]) - np.dot(x[nxt], y))
    if area2 >= 0.0:  # counter-clockwise: the size of the drive only decides a negative area
        return 1
    scale = float(np.ptp(center, axis=0).max()) ** 2
    return -1 if area2 < -1e-12 * max(scale, 1e-300) else 1


@functools.lru_cache(maxsize=16)
def _pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The index pairs (i < j) of n pulleys, row by row (read-only, cached)."""
    i_, j_ = np.triu_indices(n, 1)
    i_.setflags(write=False)
    j_.setflags(write=False)
    return i_, j_


@functools.lru_cache(maxsize=16)
def _next(n: int) -> np.ndarray:
    """(n,) the next pulley of each of n pulleys around the loop (read-only, cached)."""
    nxt = np.roll(np.arange(n), -1)
    nxt.setflags(write=False)
    return nxt


def compute_layout(
    center: np.ndarray,
    radius: np.ndarray,
    side_sign: np.ndarray,
    names: tuple[str, ...],
    *,
    orientation: int | None = None,
    check: bool = True,
    adjust_offset: float = 0.0,
    adjust_index: int | None = None,
    adjust_kind: str = "slide",
) -> Layout:
    """Tangent points, spans, wraps and belt length for pulleys in belt order (the adjust_* fields
    are carried into the Layout as given).

    check: raise GeometryError (with the key path) for overlapping pulleys, a missing tangent, a span
    that cuts through another pulley, a pulley the belt does not touch, or a path that winds wrongly
    (`check_layout`); False for an iterate whose answer is checked later.

    The spans and their ends are laid out on floats (`span_lines`; a drive has a handful of pulleys, on
    which a numpy call costs more than its arithmetic) and made arrays once; the checks first screen the
    path in one pass with the arithmetic of the checks themselves (`_path_ok`), and only a layout the
    screen flags runs the checks one by one, in their order, for the error.
    """
    center = np.array(center, dtype=float)  # (copies: the layout's arrays are its own, read-only)
    radius = np.array(radius, dtype=float)
    side_sign = np.array(side_sign, dtype=float)
    n = len(radius)
    o = loop_orientation(center) if orientation is None else orientation
    z = center.view(complex).ravel().tolist()  # points as x + iy: sums and real multiples are exact per component
    r, sigma = radius.tolist(), (o * side_sign).tolist()  # o sigma: the turning sense of each pulley
    apart = (lambda: _check_apart(center, radius, names)) if check else None
    alpha, q, wrap, sums = span_lines(z, r, sigma, coincident=apart)
    rows = np.array(alpha + wrap + sums).reshape(5, n)  # the span angles, wraps, span lengths, arcs, turns
    total_length, total_arc, total_turn = np.add.reduce(rows[2:], axis=1).tolist()
    rho = [s * x for s, x in zip(sigma, r)]
    rho1, z1 = rho[1:] + rho[:1], z[1:] + z[:1]  # pulley i + 1 of span i
    m = [complex(math.sin(a), -math.cos(a)) for a in alpha]  # the right normals sin a - i cos a
    starts = [c + x * u for c, x, u in zip(z, rho, m)]
    ends = [c + x * u for c, x, u in zip(z1, rho1, m)]
    normals = [_sign(x) * u for x, u in zip(rho + rho1, m + m)]  # at the starts, then at the ends
    points = np.array(z + starts + ends + normals).reshape(5, n)
    xy = points.view(float).reshape(5, n, 2)  # the centres, span starts, span ends, start and end normals
    for a in (center, radius, side_sign, rows, xy):  # (a layout is shared: its arrays read-only, and the
        a.setflags(write=False)  # views of them it holds)
    lay = Layout(
        names=tuple(names), center=center, radius=radius, side_sign=side_sign, orientation=o,
        span_start=xy[1], span_end=xy[2], span_length=rows[2], span_angle=rows[0], start_normal=xy[3],
        end_normal=xy[4], wrap_angle=rows[1], arc_length=rows[3], belt_length=total_length + total_arc,
        adjust_offset=adjust_offset, adjust_index=adjust_index, adjust_kind=adjust_kind,
    )
    # checked: |q| < 1 for every span (a NaN q: the turn NaN too, which `_path_ok` fails), then the rest
    if check and not (max(map(abs, q)) < 1.0 and _path_ok(radius, wrap, o, total_turn, points[:3])):
        _check_apart(center, radius, names)
        _check_tangents(np.array(q), names)
        _check_path(lay)
    return lay


def _sign(x: float) -> float:
    """np.sign of a float: -1, 0 or 1 (NaN stays NaN)."""
    return 1.0 if x > 0.0 else -1.0 if x < 0.0 else x * 0.0


def span_lines(z: Sequence[complex], radius: Sequence[float], sigma: Sequence[float], *,
               coincident: Callable[[], None] | None = None) -> tuple[list[float], ...]:
    """The tangent lines and wraps of pulleys at z (n) (complex x + iy) of radii (n) turning the belt in
    the senses sigma (n) (orientation x side), sequences of floats in, lists of floats out: (span angles a (n)
    rad, q (n) = (rho_i - rho_(i+1)) / D (the module docstring), wrap angles (n) rad, sums (3n): the span
    lengths, arc lengths and signed turning angles, n each, one after the other). A span without a
    tangent (|q| > 1: an unchecked iterate; the checks then name it) takes its angle at q clipped to
    [-1, 1]; coincident centres give q = +-inf or NaN (D = 0). coincident: called, if given, before the
    division when two neighbouring centres coincide (the checks raise there). The one place of the
    tangent-line arithmetic: `compute_layout` and `belt_path`."""
    rho = [s * r for s, r in zip(sigma, radius)]
    alpha, q, length = [], [], []
    for z0, z1, r0, r1 in zip(z, z[1:] + z[:1], rho, rho[1:] + rho[:1]):
        d = z1 - z0
        dist, drho = abs(d), r0 - r1  # abs: the C library's hypot, as np.hypot
        if dist:
            qi = drho / dist
        else:
            if coincident is not None:  # coincident centres: their overlap before q divides by zero
                coincident()
            qi = drho * math.inf if drho else math.nan  # IEEE division by +0
        alpha.append(cmath.phase(d) + math.asin(1.0 if qi > 1.0 else -1.0 if qi < -1.0 else qi))  # phase: atan2
        q.append(qi)
        h2 = dist * dist - drho * drho  # >= +0 where |q| < 1 (|drho| < dist: rounding keeps the order)
        length.append(0.0 if h2 < 0.0 else math.sqrt(h2))
    wrap = [(s * (a - b)) % TWO_PI for s, a, b in zip(sigma, alpha, alpha[-1:] + alpha[:-1])]
    return alpha, q, wrap, length + [r * w for r, w in zip(radius, wrap)] + [s * w for s, w in zip(sigma, wrap)]


def belt_path(center: np.ndarray, radius: np.ndarray, side_sign: np.ndarray, orientation: int) -> BeltPath:
    """The `BeltPath` of pulleys at `center` (n, 2) of radii (n,) on sides side_sign (n,) of a loop of
    `orientation`: the spans and wraps of `compute_layout(check=False)` (`span_lines`), without the tangent
    points, normals and checks."""
    z = np.ascontiguousarray(center, dtype=float).view(complex).ravel().tolist()
    sigma = (orientation * np.asarray(side_sign, dtype=float)).tolist()
    alpha, _, _, sums = span_lines(z, np.asarray(radius, dtype=float).tolist(), sigma)
    rows = np.array(alpha + sums).reshape(4, len(z))  # the span angles, span lengths, arcs, turns
    total_length, total_arc = np.add.reduce(rows[1:3], axis=1).tolist()
    return BeltPath(span_angle=rows[0], span_length=rows[1], arc_length=rows[2], belt_length=total_length + total_arc)


@functools.lru_cache(maxsize=16)
def _tables(n: int) -> tuple[np.ndarray, ...]:
    """Index tables of n pulleys for `_path_ok` (read-only, cached): the p pairs that the checks compare:
    the pulleys (i, k > i) of `_check_apart`, then each span i and the pulleys k not its own of
    `_check_path`: seg (3, p) indices into the points (centres; span starts; span ends) (3n,) of where
    the segment begins, of pulley k's centre and of where the segment ends (a pair's segment: pulley i's
    centre, of zero length); rad (2, p) the radii subtracted from the distance, indices into (radius, 0)
    (n + 1,): pulley i's (a pair) or none (a span), then pulley k's; limit (p,) the least gap that passes (0 apart,
    -1e-12 cut)."""
    i_, k_ = _pairs(n)
    si, sk = np.nonzero(_not_own(n))  # none for two pulleys
    seg = np.stack([np.concatenate([i_, n + si]), np.concatenate([k_, sk]), np.concatenate([i_, 2 * n + si])])
    rad = np.stack([np.concatenate([i_, np.full(len(si), n)]), np.concatenate([k_, sk])])
    limit = np.concatenate([np.zeros(len(i_)), np.full(len(si), -1e-12)])
    out = (seg, rad, limit)
    for x in out:
        x.setflags(write=False)
    return out


_ZERO = np.zeros(1)
_ZERO.setflags(write=False)


def _path_ok(radius: np.ndarray, wrap: list[float], o: int, turn: float, points: np.ndarray) -> bool:
    """True when none of the checks of `_check_apart` and `_check_path` fails (on a layout whose spans
    all have their tangent: `_check_tangents`), computed with their arithmetic in fewer numpy calls: the
    distance of a pulley's centre from another's and from a span's segment for every pair they compare,
    in one (p,) array (a centre is a segment of zero length; `_tables`). False when one would fail or a
    NaN makes it unsure (the checks then run one by one and raise the first failure as they always did).
    wrap (n) the wrap angles, turn their signed sum; points (3, n) complex x + iy: the centres, the span
    starts and the span ends."""
    if not (abs(turn - o * TWO_PI) <= 1e-6 and min(wrap) >= 1e-9 and max(wrap) <= TWO_PI - 1e-9):  # (NaN: turn)
        return False
    seg, rad, limit = _tables(len(radius))
    x = points.ravel()[seg]  # (3, p): segment start, the centre tested, segment end
    d = x[1:] - x[0]  # (2, p): r (start -> centre), ab (start -> end)
    ab = d[1]
    dots = d.real * ab.real + d.imag * ab.imag  # (2, p): r . ab, ab . ab
    t = np.minimum(np.maximum(dots[0] / np.maximum(dots[1], 1e-300), 0.0), 1.0)
    e = d[0] - t * ab  # a real multiple: exact per component, as (rx - t ax, ry - t ay)
    own, other = np.concatenate((radius, _ZERO))[rad]
    return bool((np.hypot(e.real, e.imag) - own - other >= limit).all())


def _check_apart(center: np.ndarray, radius: np.ndarray, names: tuple[str, ...]) -> None:
    """Every pair (i < j) of pulleys apart (GeometryError naming the first overlapping pair)."""
    i_, j_ = _pairs(len(radius))
    gaps = np.hypot(*(center[i_] - center[j_]).T) - radius[i_] - radius[j_]
    if np.any(gaps < 0):
        k = int(np.argmax(gaps < 0))  # the first pair in (i, j) order
        i, j = int(i_[k]), int(j_[k])
        raise GeometryError(f"pulleys '{names[i]}' and '{names[j]}' overlap by {-gaps[k]:.6g} m",
                            f"pulleys[{j}].center")


def check_layout(lay: Layout) -> None:
    """The checks of `compute_layout` on a layout computed without them: pulleys apart, a tangent for
    every span, every pulley wrapped, the path winding once, no span through another pulley."""
    center, radius, names, n = lay.center, lay.radius, lay.names, lay.n
    _check_apart(center, radius, names)
    nxt = _next(n)
    rho = lay.orientation * lay.side_sign * radius
    d = center[nxt] - center
    _check_tangents((rho - rho[nxt]) / np.hypot(d[:, 0], d[:, 1]), names)
    _check_path(lay)


def _check_tangents(q: np.ndarray, names: tuple[str, ...]) -> None:
    """A tangent line for every span: |q| < 1, q (n,) = (rho_i - rho_(i+1)) / D (the module docstring)."""
    if np.any(np.abs(q) >= 1.0):
        n = len(names)
        i = int(np.argmax(np.abs(q)))
        raise GeometryError(
            f"no tangent line from pulley '{names[i]}' to '{names[(i + 1) % n]}' "
            f"(pulleys too close for these radii and sides)", f"pulleys[{(i + 1) % n}].center")


def _check_path(lay: Layout) -> None:
    """Every pulley wrapped, the path winding once, no span through another pulley."""
    center, radius, names, n, o = lay.center, lay.radius, lay.names, lay.n, lay.orientation
    wrap = lay.wrap_angle
    bad = (wrap < 1e-9) | (wrap > TWO_PI - 1e-9)
    if bad.any():
        j = int(np.argmax(bad))
        raise GeometryError(
            f"the belt does not wrap pulley '{names[j]}' (wrap angle {math.degrees(wrap[j]):.3g} deg);"
            f" check its side and position", f"pulleys[{j}].side")
    total = float(np.sum(o * lay.side_sign * wrap))
    if abs(total - o * TWO_PI) > 1e-6:
        raise GeometryError(
            f"the belt path winds {total / TWO_PI:.3g} times instead of once: "
            "check the pulley order and sides", "pulleys")
    if n > 2:  # distance of every other pulley's centre (k) from every span's segment (i), (n, n)
        start, ab = lay.span_start, lay.span_end - lay.span_start
        rx = center[None, :, 0] - start[:, 0, None]
        ry = center[None, :, 1] - start[:, 1, None]
        ax, ay = ab[:, 0, None], ab[:, 1, None]
        t = np.minimum(np.maximum((rx * ax + ry * ay) / np.maximum(ax * ax + ay * ay, 1e-300), 0.0), 1.0)
        cut = (np.hypot(rx - t * ax, ry - t * ay) - radius < -1e-12) & _not_own(n)  # a span touches its own two
        if cut.any():
            i, k = (int(x) for x in np.argwhere(cut)[0])
            raise GeometryError(
                f"span {names[i]}-{names[(i + 1) % n]} cuts through pulley '{names[k]}'",
                f"pulleys[{k}].center")


@functools.lru_cache(maxsize=16)
def _not_own(n: int) -> np.ndarray:
    """(n, n) bool: pulley k is not one of span i's two pulleys (i, i + 1) (read-only, cached)."""
    out = np.ones((n, n), dtype=bool)
    out[np.arange(n), np.arange(n)] = False
    out[np.arange(n), (np.arange(n) + 1) % n] = False
    out.setflags(write=False)
    return out


@dataclass(frozen=True, kw_only=True)
class Motion:
    """How the adjustable pulley moves with its offset s: along a slide (s in m along the unit
    `direction` from the drawn centre) or on a tensioner arm (s the angle in rad the arm turns
    counter-clockwise about `pivot` from the drawn arm angle, a direction change: wrapped to [-pi, pi))."""

    center: np.ndarray  # (2,) m, the pulley's drawn centre
    direction: np.ndarray  # (2,) unit vector of the slide (unused on an arm)
    pivot: np.ndarray | None = None  # (2,) m, the arm's pivot; None: a slide

    @property
    def kind(self) -> str:
        return "slide" if self.pivot is None else "arm"

    @property
    def unit(self) -> str:
        return "m" if self.pivot is None else "rad"

    def point(self, s: float) -> tuple[complex, complex]:
        """The pulley's centre at offset s and d centre / ds, as x + iy."""
        (cx, cy), (dx, dy) = self.center.tolist(), self.direction.tolist()
        if self.pivot is None:
            return complex(cx + s * dx, cy + s * dy), complex(dx, dy)
        px, py = self.pivot.tolist()
        rx, ry = cx - px, cy - py
        c, sn = math.cos(s), math.sin(s)
        x, y = c * rx - sn * ry, sn * rx + c * ry  # pivot -> centre, turned by s
        return complex(px + x, py + y), complex(-y, x)

    def normalized(self, s: float) -> float:
        """The offset on its one branch: an arm's turn wrapped to [-pi, pi) (the branch nearest the
        drawing), a slide's travel as it is."""
        return s if self.pivot is None else float(wrap_angle(s))

    def slope_scale(self) -> float:
        """What a slope d length / ds is measured against (m per unit offset)."""
        return 1.0 if self.pivot is None else abs(complex(*(self.center - self.pivot).tolist()))


class _Iterate(NamedTuple):
    """An iterate of the L0 fit: the fitted length, its slope (d / ds of the belt length: the weighted
    arcs' change neglected, the iteration then converges linearly for w != 1), and its path (a checked
    `Layout`, or the unchecked `BeltPath`)."""

    length: float
    slope: float
    path: Layout | BeltPath


@dataclass(frozen=True, kw_only=True)
class _FitProblem:
    """The L0 fit of pulley `index` of the pulleys (center (n, 2), radius (n,), side_sign (n,)):
    fitted length sum(span lengths) + w sum(arc lengths) = target_length."""

    center: np.ndarray
    radius: np.ndarray
    side_sign: np.ndarray
    names: tuple[str, ...]
    orientation: int
    index: int
    motion: Motion
    target_length: float
    arc_weight: float

    @property
    def name(self) -> str:
        return self.names[self.index]

    def _centers(self, s: float) -> tuple[np.ndarray, complex]:
        """The centres (n, 2) with the pulley at offset s, and its d centre / ds (x + iy)."""
        c, (p, v) = self.center.copy(), self.motion.point(s)
        c[self.index] = p.real, p.imag
        return c, v

    def layout_at(self, s: float, check: bool) -> Layout:
        """The layout at offset s (its adjust_* fields: s, of this pulley and motion)."""
        return compute_layout(self._centers(s)[0], self.radius, self.side_sign, self.names, orientation=self.orientation,
                              check=check, adjust_offset=s, adjust_index=self.index, adjust_kind=self.motion.kind)

    def at(self, s: float, check: bool) -> _Iterate:
        """The iterate at offset s: of its checked layout (check), else of its unchecked path (`belt_path`)."""
        if check:
            return self.of_path(s, self.layout_at(s, True))
        c, v = self._centers(s)
        return self._iterate(v, belt_path(c, self.radius, self.side_sign, self.orientation))

    def of_path(self, s: float, path: Layout | BeltPath) -> _Iterate:
        """The iterate of the layout or path at offset s."""
        return self._iterate(self.motion.point(s)[1], path)

    def _iterate(self, v: complex, path: Layout | BeltPath) -> _Iterate:
        """The iterate of a path where the pulley's centre moves at v = d centre / ds: its slope g . v with
        the belt length's gradient g = t_in - t_out at the pulley (the arriving span's direction minus the
        departing one's: the module docstring)."""
        j, w = self.index, self.arc_weight
        a, b = path.span_angle[j - 1].item(), path.span_angle[j].item()
        gx, gy = math.cos(a) - math.cos(b), math.sin(a) - math.sin(b)
        length = path.belt_length if w == 1.0 else path.belt_length + (w - 1.0) * float(path.arc_length.sum())
        return _Iterate(length, gx * v.real + gy * v.imag, path)

    def where(self) -> tuple[str, str]:
        if self.motion.pivot is None:
            return "moving pulley", "along its slide"
        return "turning the arm of pulley", "about its pivot"


def _fit_newton(fit: _FitProblem, start: _Iterate, *, check: bool, tol: float,
                max_iter: int) -> tuple[float, _Iterate]:
    """Newton on the offset s from 0 (iterate `start`) until the fitted length meets the target,
    backtracking when a step leaves the feasible region (check: the iterates' layouts checked) or does
    not reduce the misfit.
    Returns (s, the iterate at s); GeometryError when L0 cannot be reached."""
    how, where = fit.where()
    target, motion = fit.target_length, fit.motion
    s, it, scale = 0.0, start, motion.slope_scale()
    for _ in range(max_iter):
        f = it.length - target
        if abs(f) <= tol * target:
            return s, it
        if not abs(it.slope) >= 1e-9 * scale:
            raise GeometryError(
                f"{how} '{fit.name}' {where} does not change the belt length "
                + ("(slide_direction perpendicular to the belt pull)" if motion.pivot is None else
                   "(the arm points along the belt pull)"),
                f"pulleys[{fit.index}].{'slide_direction' if motion.pivot is None else 'arm_pivot'}")
        step = -f / it.slope
        trial = f_trial = None
        for _ in range(60):
            try:
                trial = fit.at(s + step, check)
            except GeometryError:
                step *= 0.5
                continue
            f_trial = trial.length - target
            if abs(f_trial) < abs(f) or abs(step) < 1e-15:
                break
            step *= 0.5
        if trial is None or not abs(f_trial) < abs(f):
            word = "short" if f > 0 else "long"
            raise GeometryError(
                f"L0 = {target:.6g} m is too {word}: {how} '{fit.name}' {where} cannot make the belt fit "
                f"(closest belt length {it.length:.6g} m at offset {s:.6g} {motion.unit})", "belt.length")
        s, it = motion.normalized(s + step), trial
    raise GeometryError(f"L0 fit did not converge (belt length {it.length:.9g} m)", "belt.length")


def _range_error(fit: _FitProblem, s: float, lay: Layout, slide_range: tuple[float, float]) -> GeometryError:
    """The fitted offset s outside slide_range (an arm: its stops about the drawn arm angle)."""
    word = "short" if s * fit.of_path(s, lay).slope < 0 else "long"
    if fit.motion.pivot is None:
        return GeometryError(
            f"L0 = {fit.target_length:.6g} m is too {word} to reach along the slide of pulley '{fit.name}': "
            f"needs an offset of {s:.6g} m, slide_range is [{slide_range[0]:g}, {slide_range[1]:g}] m",
            "belt.length")
    phi0 = pivot_angle(fit.motion.center, fit.motion.pivot)  # the drawn arm angle, as the stops are counted from
    return GeometryError(
        f"the stops exclude the fitted arm angle: L0 = {fit.target_length:.6g} m needs the arm of pulley "
        f"'{fit.name}' at {phi0 + s:.6g} rad ({math.degrees(phi0 + s):.4g} deg), its stops are "
        f"[{phi0 + slide_range[0]:g}, {phi0 + slide_range[1]:g}] rad (move the stops or change L0)",
        f"pulleys[{fit.index}].arm_range")


def fit_adjustable(
    center: np.ndarray,
    radius: np.ndarray,
    side_sign: np.ndarray,
    names: tuple[str, ...],
    *,
    index: int,
    direction: np.ndarray,
    target_length: float,
    slide_range: tuple[float, float] | None = None,
    pivot: np.ndarray | None = None,
    arc_weight: float = 1.0,
    orientation: int | None = None,
    tol: float = 1e-13,
    max_iter: int = 100,
    base: Layout | None = None,
) -> Layout:
    """Newton on the offset s along `direction` of pulley `index` until the belt length equals L0.

    With a `pivot` (a tensioner arm) s is the angle (rad, counter-clockwise) the arm turns about the
    pivot instead, wrapped to [-pi, pi) (the branch nearest the drawing), and slide_range bounds that
    angle offset. With arc_weight w != 1 the length fitted is sum(span lengths) + w sum(arc lengths)
    (the path of a belt whose spans are stretched by w and whose wraps are not, times w: see `static`);
    the slope is then that of the belt length, and the iteration converges linearly. Backtracks when a
    step leaves the feasible region; raises GeometryError (key belt.length) when L0 cannot be reached. base: the layout
    at `center`, if known.

    The iterates are laid out unchecked (the drawn centre is only where the fit starts) and the answer
    laid out and checked; on any failure the fit runs again with every iterate checked, from the checked
    layout at the drawn centre, for the error that names the cause.
    """
    center = np.array(center, dtype=float)
    motion = Motion(center=center[index].copy(), direction=np.asarray(direction, dtype=float),
                    pivot=None if pivot is None else np.asarray(pivot, dtype=float))
    if base is not None:
        orientation = base.orientation
    elif orientation is None:
        orientation = loop_orientation(center)
    radius, side_sign = np.asarray(radius, dtype=float), np.asarray(side_sign, dtype=float)
    fit = _FitProblem(center=center, radius=radius, side_sign=side_sign, names=tuple(names), orientation=orientation,
                      index=index, motion=motion, target_length=float(target_length), arc_weight=float(arc_weight))
    try:
        start = fit.of_path(0.0, base) if base is not None else fit.at(0.0, False)
        s, _ = _fit_newton(fit, start, check=False, tol=tol, max_iter=max_iter)
        lay = fit.layout_at(s, check=True)
    except GeometryError:
        if base is None:
            try:
                base = fit.layout_at(0.0, check=True)
            except GeometryError as exc:
                raise GeometryError(f"at the given centre of the adjustable pulley: {exc}", exc.key) from None
        s, end = _fit_newton(fit, fit.of_path(0.0, base), check=True, tol=tol, max_iter=max_iter)
        lay = replace(end.path, adjust_offset=s, adjust_index=index, adjust_kind=motion.kind)
    if slide_range is not None and not (slide_range[0] <= s <= slide_range[1]):
        raise _range_error(fit, s, lay, slide_range)
    return lay


def relay(layout: Layout, center: np.ndarray, *, adjust_offset: float | None = None, check: bool = True) -> Layout:
    """The same belt path laid anew with the pulleys at `center` (n, 2): tangent points, spans,
    wraps and belt length recomputed, the loop's orientation kept. adjust_offset: the adjustable
    pulley's travel from its given centre at `center` (default: unchanged). check: as `compute_layout`
    (False: an iterate whose answer is checked later)."""
    return compute_layout(center, layout.radius, layout.side_sign, layout.names, orientation=layout.orientation,
                          check=check, adjust_index=layout.adjust_index, adjust_kind=layout.adjust_kind,
                          adjust_offset=layout.adjust_offset if adjust_offset is None else float(adjust_offset))


def fit_inputs(cfg: DriveConfig) -> tuple:
    """What `layout_from_config` reads of a configuration, as a key (hashable, compared by value): the
    pulleys and the belt's length. Configurations with equal keys have the same L0 fit (`reuse.Reuse`: a
    study's analyses of one geometry share it)."""
    return cfg.pulleys, float(cfg.belt.length)


def layout_from_config(cfg: DriveConfig) -> Layout:
    """The geometry of a drive: L0 fit when a pulley is adjustable, else the given centres."""
    pulleys = cfg.pulleys
    center = np.array([v for p in pulleys for v in p.center], dtype=float).reshape(len(pulleys), 2)
    radius = np.array([p.radius for p in pulleys], dtype=float)
    side = np.array([1.0 if p.side == "inside" else -1.0 for p in pulleys])
    names = tuple([p.name for p in pulleys])
    try:
        a = cfg.adjustable_index
        if a is None:
            lay = compute_layout(center, radius, side, names)
        else:
            from beltdyn.model.supports import support_of

            lay = fit_adjustable(center, radius, side, names, index=a, target_length=cfg.belt.length,
                                 **support_of(cfg.pulleys[a]).fit_motion())
    except GeometryError as exc:
        raise ConfigError(str(exc), file=cfg.source, key=exc.key) from None
    for j, p in enumerate(cfg.pulleys):  # stops that exclude the (fitted) arm angle
        if p.support == "arm" and p.arm_range is not None:
            phi = unwrap_near(arm_angle(lay, j, p.arm_pivot), sum(p.arm_range) / 2)
            if not p.arm_range[0] <= phi <= p.arm_range[1]:
                raise ConfigError(f"the arm of pulley '{p.name}' sits at {phi:.6g} rad, outside its stops "
                                  f"[{p.arm_range[0]:g}, {p.arm_range[1]:g}] rad", file=cfg.source,
                                  key=f"pulleys[{j}].arm_range")
    return lay


def arm_angle(layout: Layout, j: int, pivot) -> float:
    """The angle (rad, counter-clockwise from +x) of the arm pivot (2,) -> centre of pulley j."""
    return pivot_angle(layout.center[j], pivot)


def travel_sense(layout: "Layout", j: int) -> float:
    """+1 if a counter-clockwise turn of pulley j advances the belt along its direction of travel, else -1:
    the sign of (z x n) . t at the tangent point where span j leaves pulley j."""
    n = layout.start_normal[j]
    t = layout.span_direction[j]
    return 1.0 if float(-n[1] * t[0] + n[0] * t[1]) >= 0.0 else -1.0


def belt_speed_of(cfg: "DriveConfig", layout: "Layout") -> float:
    """The belt speed c (m/s) that [running] asks for: belt_speed, or driver_speed x R_driver with the
    sense of travel (`travel_sense`); 0 without [running]."""
    r = cfg.running
    if r is None:
        return 0.0
    if r.belt_speed is not None:
        return float(r.belt_speed)
    if r.driver_speed is not None:
        d = cfg.driver_index
        return float(r.driver_speed) * float(layout.radius[d]) * travel_sense(layout, d)
    return 0.0


def driver_speed_of(belt_speed: float, layout: "Layout", driver: int) -> float:
    """The driver's angular speed (rad/s, counter-clockwise) at the belt speed c: c / R_driver with the
    sense of travel."""
    return float(belt_speed) / float(layout.radius[driver]) * travel_sense(layout, driver)
