"""Nonlinear static equilibrium: Newton with load stepping and line search.

Residual (reduced coordinates q, DESIGN section 2, paper Eq. 24 without inertia):
    R(q) = f_int(q) + k_s q - p - lambda f_g,
f_int the belt's internal force (Eqs. 14, 17) mapped through the joints, k_s the bearing springs
(Eq. 21) with preload p, f_g the weight (Eq. 8), lambda the load factor. The driver pulley's rotation
is held (it reacts the applied torques and removes the belt's rigid rotation). With tension mode
"adjust" the equation of the adjustable pulley's slide is replaced by  T(q) - T_target = 0,  T the
length-weighted mean true axial force of the spans: moving the pulley sets the tension and the
bearing spring's preload follows from the slide equation afterwards; the travel it takes is held to
the pulley's slide_range (a SolverError names the pulley, the travel needed and the limit).

Convergence is measured per DOF group (`ResidualScales`): span rows against the tension scale,
rotation rows against the torque scale tension x pulley radius, translation rows against the forces
on the pulley (belt pull, weight, the bearing spring's force from the displacement, not a constant
preload), each plus the belt's round-off floor; err <= 1 means converged.

Solved geometry (`solve_static_on_solved_geometry`, what `pipeline.analyse` runs). One system keeps
the tangent points of its layout: a pulley that moves in the solve (the tension travel, a bearing's
deflection) meets its spans off tangent, and a free pulley's two span tensions then differ. So the
belt is laid out anew at the solved pulley centres (`geometry.relay`), the system rebuilt and solved
again until the pulleys stay where they are laid (movement <= tolerance x the shortest span; one or
two passes with the predictor, a few more when bearings deflect). The belt's stress-free state: in
mode "adjust" it is the belt of undeformed length L0 over spans and wraps, the wraps unstretched
(DESIGN section 2: spans stress-free in the L0 geometry, the tension from moving the pulley); where
a tangent point moves along its pulley, that arc of belt passes between span and wrap
(`carried_reference`), so sum(span reference lengths) + sum(R_j wrap_j) = L0 on every layout, and
the bordered Newton meets the target on the final one. In mode "prestrain" the spans' common stretch
is iterated (secant) until the mean tension meets the target with every pulley free on its bearing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from operator import mul, truediv

import numpy as np

from beltdyn.config import StaticOptions
from beltdyn.errors import SolverError
from beltdyn.model.angles import TWO_PI, pivot_angle, unwrap_near
from beltdyn.model.geometry import GeometryError, Layout, MovingPulley, fit_adjustable, relay
from beltdyn.model.slip import required_friction, slip_margin
from beltdyn.model.barlaw import stretch_for_tension, stretch_start
from beltdyn.model.dofs import DOF_GROUPS
from beltdyn.model.system import System


@dataclass(frozen=True, kw_only=True)
class StaticResult:
    """Equilibrium. Shapes: n_dof, n_span = n_pulley = n."""

    q: np.ndarray  # (n_dof,) independent coordinates at equilibrium
    spring_preload: np.ndarray  # (n_dof,) bearing spring preload p (N)
    span_tension: np.ndarray  # (n, 2) axial force at the start/end of each span (joint reactions), N
    mean_tension: float  # N, length-weighted mean over all spans
    hub_load: np.ndarray  # (n, 2) force of the belt on each pulley, N
    pulley_center: np.ndarray  # (n, 2) m
    pulley_rotation: np.ndarray  # (n,) rad
    driver_torque: float  # N m, torque the driver's support applies to hold it
    adjust_offset: float  # m, total travel of the adjustable pulley from its given centre
    residual_history: np.ndarray  # (n_iter,) residual norm / allowed residual after each Newton iteration
    load_factor_history: np.ndarray  # (n_iter,) load factor of each iteration
    iterations: int
    tension_mode: str
    # tensioner arms (NaN for pulleys without one), the static load case and the slip margins
    arm_angle: np.ndarray | None = None  # (n,) rad, counter-clockwise from +x
    arm_torque: np.ndarray | None = None  # (n,) N m, torque of the arm's spring on the arm (counter-clockwise +)
    arm_free_angle: np.ndarray | None = None  # (n,) rad, the spring's free angle (what mode "adjust" needs)
    pivot_reaction: np.ndarray | None = None  # (n, 2) N, force of the pivot on the arm
    applied_torque: np.ndarray | None = None  # (n,) N m, the accessory torques of the static load case
    required_friction: np.ndarray | None = None  # (n,) ln(T_tight / T_slack) / wrap (inf: a slack span)
    slip_margin: np.ndarray | None = None  # (n,) friction / required_friction (NaN: no friction given)


def _predictor(system: System, stretch: float | np.ndarray, adjust_dof: int, driver_dof: int) -> np.ndarray:
    """Linear axial estimate: rotations and the adjustable slide (adjust_dof >= 0) that stretch the spans
    by `stretch` (one number, or one per span).

    Span elongation d_s = (dr_end - dr_start) . t_s is linear in the pulley DOFs; solve A x = (stretch-1) L_s
    (least squares) for the non-driver rotations and the slide, then lay the nodes on the straight chords.
    """
    model = system.belt
    n = system.layout.n
    rot = system.rot_dof
    unknowns = rot[rot != driver_dof]
    if adjust_dof >= 0:
        unknowns = np.append(unknowns, adjust_dof)
    A_p = np.zeros((n, system.n_p + 1))  # on the joint coordinates (an arm's centre offsets), padding last
    t = model.reference_direction
    if model.elements.n_elem:
        flex = model.flexible
        span = np.repeat(flex, model.idx.shape[1])
        for els, rows, sign in ((model.first, slice(0, 2), -1.0), (model.last, slice(4, 6), 1.0)):
            coef = sign * np.einsum("sdk,sd->sk", model.T[els, rows, :], t[flex])  # (n_flex, m): d(elongation)/d(dof)
            np.add.at(A_p, (span, model.idx[els].ravel()), coef.ravel())
    sp = system.springs
    if sp is not None:  # a spring span's ends: the same joints; its chord's map D = dd/dp
        D, ts = sp.chord_map, t[sp.span]
        # (a span's columns: distinct DOFs, and the padding's zeros; the spans are not the ANCF ones)
        A_p[sp.span[:, None], sp.idx] += D[:, 0] * ts[:, 0, None] + D[:, 1] * ts[:, 1, None]
    A_p = A_p[:, : system.n_p]
    A_q = A_p if system.arms is None else system.arms.project(None, A_p)  # A_p J at q = 0
    A = A_q[:, unknowns]
    lam0 = model.span_stretch if model.span_stretch is not None else model.prestrain_stretch
    target = (stretch - lam0) * model.reference_length  # elongation still needed from the stretch at q = 0
    # the normal equations: a few unknowns, a start for Newton (SVD least squares if singular); LAPACK's
    # dgesv directly (np.linalg.solve's call, without its gufunc set-up: most of its time on 6 unknowns)
    from scipy.linalg.lapack import dgesv

    q = np.zeros(system.n_dof)
    if len(unknowns):  # (at least the non-driver pulleys' rotations)
        _, _, x, info = dgesv(A.T @ A, A.T @ target)
        q[unknowns] = x if info == 0 else np.linalg.lstsq(A, target, rcond=None)[0]
    return _straight_spans(system, q)


def _straight_spans(system: System, q: np.ndarray) -> np.ndarray:
    """q with every span laid straight between its end nodes (where q's pulley DOFs put them), its
    nodes evenly spaced and its gradients the chord over the reference length (the stretch)."""
    model = system.belt
    q = q.copy()
    if not model.elements.n_elem:  # every span a spring: no nodes of their own
        return q
    e = model.element_coordinates(system.expand(q))
    for s, els in enumerate(model.span_elements):
        n_e = len(els)
        if not n_e:  # a spring span: no nodes of its own
            continue
        frac = np.arange(1, n_e) / n_e
        e_first, e_last = els[0], els[-1]
        a, b = e[e_first, 0:2], e[e_last, 4:6]
        grad = (b - a) / model.reference_length[s]
        nodes = np.empty((n_e - 1, 4))
        nodes[:, 0:2] = a + np.outer(frac, b - a) - model.e0[els[1:], 0:2]
        nodes[:, 2:4] = grad - model.e0[els[1:], 2:4]
        q[system.dofs.span_slices[s]] = np.concatenate([grad - model.e0[e_first, 2:4], nodes.ravel(),
                                                        grad - model.e0[e_last, 6:8]])
    return q


def _pin(K, pinned: np.ndarray, dense: bool):
    """Hold the `pinned` DOFs: their rows and columns become those of the identity (in place)."""
    if dense:
        K[pinned, :] = 0.0
        K[:, pinned] = 0.0
        K[pinned, pinned] = 1.0
        return K
    rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    hold = np.zeros(K.shape[0], dtype=bool)
    hold[pinned] = True
    K.data[hold[rows] | hold[K.indices]] = 0.0
    K.data[hold[rows] & (rows == K.indices)] = 1.0  # the pattern always holds the diagonal
    return K


def _solve(K, rhs: np.ndarray, dense: bool, rank1=None) -> np.ndarray:
    """Solve K x = rhs, or (K + e_a u^T) x = rhs for rank1 = (a, u) (Sherman-Morrison, sparse)."""
    if dense:
        return np.linalg.solve(K, rhs)
    from scipy.sparse.linalg import splu

    try:
        lu = splu(K.tocsc())
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise np.linalg.LinAlgError(str(exc)) from None
    if rank1 is None:
        x = lu.solve(rhs)
    else:
        a, u = rank1
        ea = np.zeros_like(rhs)
        ea[a] = 1.0
        y, z = lu.solve(rhs), lu.solve(ea)
        denom = 1.0 + float(u @ z)
        if abs(denom) < 1e-14 * (1.0 + abs(float(u @ z))):
            raise np.linalg.LinAlgError("singular bordered system")
        x = y - z * (float(u @ y) / denom)
    if not np.all(np.isfinite(x)):
        raise np.linalg.LinAlgError("singular matrix")
    return x


def _null_dof(K, dense: bool, labels: tuple[str, ...], rank1=None) -> str:
    """Label of the DOF with the largest share of the (near-)null vector of K."""
    Kd = np.array(K) if dense else K.toarray()
    if rank1 is not None:
        Kd[rank1[0], :] += rank1[1]
    w, v = np.linalg.eig(Kd) if rank1 is not None else np.linalg.eigh(0.5 * (Kd + Kd.T))
    vec = np.real(v[:, int(np.argmin(np.abs(w)))])
    return labels[int(np.argmax(np.abs(vec)))]


class ResidualScales:
    """The allowed static residual of each row, by DOF group (`DofMap.group`):

    - span rows: tol * S + floor, S the tension scale: the target tension (or, without one, the
      spans' prestrain force EA (lambda^3 - lambda)/2), at least the largest weight on a span row
      and 1e-9 EA;
    - rotation rows of pulley j: tol * max(S R_j, |weight torque|, |K q|) + floor R_j, a torque scale
      (N m) with R_j the pulley's radius: a tension error dT on one side of a free pulley is a torque
      error dT R_j;
    - translation rows: tol * max(S, |weight|, |K| |q|) + floor, the forces on the pulley: the belt
      pull, its weight and the force of its bearing spring from the displacement q in this system
      (sum_k |K_ik q_k|); a constant spring preload does not count (it would hide errors of the
      size of the tolerance times the preload).

    floor: the belt's round-off (eps_GL = (r'.r' - 1)/2 loses ~machine epsilon, times EA, per Gauss
    point, and the bending force's share), in N.
    """

    def __init__(self, system: System, *, EA: float | None = None, external: np.ndarray | None = None) -> None:
        """EA, external: the system's `EA` and `external_force(1.0)` if at hand."""
        d = system.dofs
        self.system = system
        self.group = group = d.group[: d.n_q]
        self.other = group != _SPAN
        self.lever = lever = np.ones(d.n_q)  # m: converts a force scale into the row's scale
        lever[d.rot_dof] = system.layout.radius
        a = system.arms
        self._arm_lever = None
        if a is not None:  # an arm's row is a torque about its pivot: the arm length
            lever[a.dof] = a.length
            self._arm_lever = np.abs(a.reference_slopes)  # (a, 2) |dc/dphi| at q = 0
        target = system.tension.target
        EA = system.EA if EA is None else EA
        if target is not None:
            S = abs(float(target))
        else:
            lam = system.belt.span_stretch if system.belt.span_stretch is not None else system.belt.prestrain_stretch
            lam = np.asarray(lam, dtype=float)
            S = float(np.abs(0.5 * EA * (lam**3 - lam)).max(initial=0.0))
        self.tension_scale = max(S, 1e-9 * EA)
        external = system.external_force(1.0) if external is None else external
        self.weight = self._on_q(np.abs(external))  # weight and accessory torques
        # the largest weight on a span row
        self._span_weight = float(self.weight[~self.other].max()) if not self.other.all() else 0.0
        self._base = (None, None)  # (|load factor|, the scale before |K| |q|) of the last `scale`
        self.K_abs = None  # |K| of the components' stiffness on the joint coordinates
        if system.linear_stiffness is not None:
            K = system.linear_matrix()
            self.K_abs = np.abs(K) if system.dense else abs(K)

    @property
    def span(self) -> np.ndarray:
        """(n,) bool: the span rows."""
        return ~self.other

    @property
    def translation(self) -> np.ndarray:
        """(n,) bool: the translation rows."""
        return self.group == _TRANSLATION

    def _on_q(self, x: np.ndarray) -> np.ndarray:
        """A non-negative scale on the joint coordinates (n_p,) -> on q: |J|^T x at q = 0."""
        a = self.system.arms
        if a is None:
            return x
        out = x[: a.n_q].copy()
        out[a.dof] += (self._arm_lever * x[a.n_q:].reshape(-1, 2)).sum(axis=1)
        return out

    def scale(self, q: np.ndarray, lam: float, p: np.ndarray | None = None) -> np.ndarray:
        """(n,) the force (N) or torque (N m) scale of each row (p: q on the joint coordinates, if at hand)."""
        c = abs(lam)
        c_last, out = self._base
        if c != c_last:
            S = max(self.tension_scale, c * self._span_weight)  # (= the largest of c weight on the span rows)
            out = np.maximum(S * self.lever, c * self.weight)
            self._base = (c, out)
        if self.K_abs is None:
            return out.copy()
        kq = self.K_abs @ np.abs(self.system.expand(q) if p is None else p)
        kq = self._on_q(kq if self.system.dense else np.asarray(kq).ravel())
        return np.maximum(out, kq, out=out.copy(), where=self.other)

    def allowed(self, q: np.ndarray, lam: float, tol: float, floor: float, p: np.ndarray | None = None) -> np.ndarray:
        """(n,) the allowed residual of each row: tol * scale + floor (times the lever arm); p: q on the
        joint coordinates, if at hand."""
        out = self.scale(q, lam, p)
        out *= tol
        out += floor * self.lever
        return out


_EPS = float(np.finfo(float).eps)
_SPAN, _ROTATION, _TRANSLATION = (DOF_GROUPS.index(g) for g in ("span", "rotation", "translation"))


class _Stop(Exception):
    """A static solve that ends without an equilibrium: message, scaled residual, DOF label at fault."""

    def __init__(self, message: str, err: float, dof: str) -> None:
        super().__init__(message)
        self.err, self.dof = err, dof


class _Fail(_Stop):
    """A failed Newton solve, which the fallbacks (smaller load steps, other starts, continuations) retry."""


class _Exhausted(_Stop):
    """The static analysis spent its budget of residual evaluations (`Budget`): not a `_Fail`, so no
    fallback catches it; `solve_equilibrium` reports it."""


EVALUATIONS_PER_ITERATION = 100  # the budget of a static analysis: this many x static.max_iterations


@dataclass(kw_only=True)
class Budget:
    """Residual evaluations a static analysis may spend, over all its solves (Newton iterations, line
    searches, load steps, continuations, tension and prestrain loops, re-lay passes): a drive with no
    equilibrium within reach fails by name within a bounded time instead of multiplying its nested
    retries (measured: a fuzzed drive on 100 N/m bearings under 3 kN spent 40 000 evaluations, 22 s,
    in one of its 40 prestrain solves). `limit`: EVALUATIONS_PER_ITERATION x static.max_iterations."""

    limit: int
    used: int = 0
    err: float = float("inf")  # the scaled residual and the DOF at fault of the last evaluation
    dof: str = ""

    @classmethod
    def of(cls, options: StaticOptions) -> "Budget":
        return cls(limit=EVALUATIONS_PER_ITERATION * int(options.max_iterations))

    def spend(self) -> None:
        """Count one evaluation; _Exhausted once the limit is reached."""
        if self.used >= self.limit:
            raise _Exhausted(f"no equilibrium within {self.limit} residual evaluations (the static analysis's "
                             f"budget, {EVALUATIONS_PER_ITERATION} x static.max_iterations): the drive finds no "
                             f"equilibrium near its layout (supports too soft for the tension, or a mechanism)",
                             self.err, self.dof)
        self.used += 1


class _Problem:
    """The static equations of one drive: residual, Jacobian and Newton with line search.

    Held ("pinned") DOFs keep their value: their residual rows are zero and their Jacobian rows and
    columns those of the identity. Each residual row is scaled by its allowed residual (`allowed`),
    so that err = max |R_i| / allowed_i <= 1 means converged.
    """

    def __init__(self, system: System, opts: StaticOptions, budget: Budget | None = None) -> None:
        self.model, self.opts = system, opts
        self.budget = budget if budget is not None else Budget.of(opts)
        self.target = system.tension.target
        self.a = system.tension.adjust_dof
        self.adjust = self.target is not None and self.a >= 0
        self.driver = system.driver_dof
        self.preload = np.zeros(system.n_dof)
        # Round-off floor of the residual: the axial force loses ~eps of EA per Gauss point, the linear
        # bending force ~eps of sum_j |K_b,ij| |e_j| (positions of order 1 m through stiff short elements).
        el = system.belt.elements
        bend = float((np.abs(el.K_bend) @ np.abs(system.belt.e0)[:, :, None]).max(initial=0.0)) if el.n_elem else 0.0
        n_sp = 0 if system.springs is None else len(system.springs.span)
        self.EA = EA = system.EA
        self.noise = 1e3 * _EPS * (EA * math.sqrt(el.n_elem + n_sp) + bend)
        self.history: list[tuple[float, float]] = []
        external = system.external_force(1.0)
        self.has_load = bool(external.any())  # (any entry != 0)
        self.has_weight = bool(system.gravity.any())
        self.accept = 1.0  # Newton stops at err <= accept (a continuation's intermediate stages: looser)
        self.scales = ResidualScales(system, EA=EA, external=external)
        # (q, load factor, driver residual, mean tension, tangent, joint coordinates) of the last evaluation
        self.last: tuple = (None, 0.0, 0.0, None, None, None)
        self.keep_tangent = False  # keep the unpinned tangent of the last evaluation (what the modal analysis reuses)

    def tension_tolerance(self) -> float:
        """Allowed error of the mean tension: relative tolerance + round-off of EA eps (~EA * eps)."""
        return self.opts.tolerance * abs(self.target) + 100 * _EPS * self.EA

    def allowed(self, q: np.ndarray, lam: float, p: np.ndarray | None = None) -> np.ndarray:
        return self.scales.allowed(q, lam, self.opts.tolerance, self.noise, p)

    def evaluate(self, q: np.ndarray, lam: float, pinned: np.ndarray, bordered: bool):
        """Residual (pinned rows zero), Jacobian, err = max scaled |R|, and the bordered rank-1 term."""
        m = self.model
        self.budget.spend()
        R, K, p = m.equilibrium(q, lam, joint=True)  # J^T (f - lam F), F the weight and the accessory torques
        R -= self.preload
        # what the outputs reuse at the solution (the tangent before bordering and pinning change it in place)
        self.last = (q, lam, float(R[self.driver]), None, K.copy() if self.keep_tangent else None, p)
        scaled = np.abs(R) / self.allowed(q, lam, p)
        rank1 = None
        if bordered:  # the slide equation of the adjustable pulley becomes T(q) = target
            T, dT = m.mean_tension_and_gradient(q)
            self.last = (q, lam, self.last[2], T, self.last[4], p)
            R[self.a] = T - self.target
            scaled[self.a] = abs(R[self.a]) / self.tension_tolerance()
            if m.dense:
                K[self.a, :] = dT
            else:
                row = K.getrow(self.a).toarray().ravel()
                rank1 = (self.a, dT - row)
        R[pinned] = 0.0
        scaled[pinned] = 0.0
        K = _pin(K, pinned, m.dense)
        if rank1 is not None:
            rank1[1][pinned] = 0.0
            # the pinned identity row of `a` (if any) is untouched by pinning only other DOFs
        worst = int(scaled.argmax())  # what a spent budget reports
        self.budget.err, self.budget.dof = float(scaled[worst]), m.dof_labels[worst]
        return R, K, float(scaled[worst]), rank1

    def newton(self, q: np.ndarray, lam: float, pinned: np.ndarray, *, bordered: bool = False,
               max_iterations: int | None = None, line_search: bool = True, stall: bool = False) -> np.ndarray:
        """Newton from q. line_search: steps shortened (halved) until the largest scaled residual
        decreases; without it every step is taken whole (a continuation stage, whose predictor is
        close: there the first step of a sagging string may raise the largest residual a thousandfold
        on its way to converging, which a line search on that merit stalls on). stall: give up
        (_Fail) at the first step the line search cuts below 1/16 (the sign of such a stall)."""
        m = self.model
        labels = m.dof_labels
        n_max = self.opts.max_iterations if max_iterations is None else max_iterations
        R, K, err, rank1 = self.evaluate(q, lam, pinned, bordered)
        for it in range(n_max):
            if err <= self.accept:
                return q
            try:
                dq = _solve(K, -R, m.dense, rank1)
            except (np.linalg.LinAlgError, RuntimeError):
                dof = _null_dof(K, m.dense, labels, rank1)
                raise _Fail(f"singular tangent stiffness in Newton iteration {it + 1} "
                            f"(no stiffness against a motion of '{dof}')", err, dof) from None
            alpha = 1.0
            for _ in range(12 if line_search else 1):
                q_try = q + alpha * dq
                R_t, K_t, err_t, r1_t = self.evaluate(q_try, lam, pinned, bordered)
                if np.isfinite(err_t) and (err_t < err * (1.0 - 1e-4 * alpha) or err_t <= self.accept
                                           or not line_search):
                    break
                alpha *= 0.5
                if stall and alpha < 1.0 / 16:
                    raise _Fail(f"Newton stalls in iteration {it + 1} (line search step {alpha:.3g})", err,
                                labels[int(np.argmax(np.abs(R)))])
            else:
                raise _Fail(f"line search failed in Newton iteration {it + 1}", err,
                            labels[int(np.argmax(np.abs(R)))])
            q, R, K, err, rank1 = q_try, R_t, K_t, err_t, r1_t
            self.history.append((err, lam))
        if err <= self.accept:
            return q
        raise _Fail(f"Newton did not converge in {n_max} iterations", err, labels[int(np.argmax(np.abs(R)))])

    def continuation(self, q: np.ndarray, pinned: np.ndarray, *, bordered: bool = False) -> np.ndarray:
        """Load stepping on the weight, halving the increment on failure."""
        if not self.has_load:
            return self.newton(q, 1.0, pinned, bordered=bordered)
        lam_done, dlam = 0.0, 1.0 / self.opts.load_steps
        while lam_done < 1.0:
            lam = min(1.0, lam_done + dlam)
            try:
                q = self.newton(q, lam, pinned, bordered=bordered)
            except _Fail as fail:
                if dlam < 1.0 / 1024:
                    fail.lam = lam  # type: ignore[attr-defined]
                    raise
                dlam *= 0.5
                continue
            lam_done, dlam = lam, 2.0 * dlam
        return q

    def start_tension(self) -> float:
        """The mean tension from which a tension continuation starts: where the straight spans take
        their sag under the weight in a few Newton iterations. A span of chord L under the weight w
        per length (its component across the chord, at most |g| rho) sags s = w L^2 / (8 T) in the
        linear (parabola) estimate, which lengthens it by (8/3) (s/L)^2 L, a tension EA w^2 L^2 /
        (24 T^2): Newton's first step overshoots the tension by this much, so the continuation starts
        where it is at most T, T^3 >= EA w^2 L^2 / 24, doubled for margin (and never below the target)."""
        m = self.model
        el = m.belt.elements
        w = float(np.linalg.norm(m.gravity)) * float(el.rho.max())
        L = float(m.layout.span_length.max())
        return max(abs(float(self.target)), 2.0 * (self.EA * (w * L) ** 2 / 24.0) ** (1.0 / 3.0))

    def tension_continuation(self, q_at, pinned: np.ndarray) -> np.ndarray:
        """Continuation in the tension target for sagging spans (low tension under the weight, little
        or no bending stiffness), where Newton from straight spans overshoots (the sag's elongation
        times EA) and a line search on the largest residual stalls.

        The bordered Newton (full steps, `newton(line_search=False)`) solves at `start_tension` from
        straight spans `q_at(T)`, then at targets lowered geometrically to the given one, with u = 1/T
        as the continuation parameter (a string's sag is linear in 1/T: the parabola s = w L^2 u / 8).
        Predictor from the last solution q_k: its tangent dq/du = -T^2 dq/dT, K_b dq/dT = e_a (the
        derivative of [R_eq; T(q) - T_target] = 0 by the target), plus the curvature that the
        solution before it adds (quadratic extrapolation in u). A stage solved in <= 3 iterations
        squares the ratio between targets (first 4); a stage not solved in 8 takes its square root
        and starts again from the same solution. The intermediate stages are solved to 100 times
        the tolerance (the next predictor's error is far larger), the last one to the tolerance.
        Returns q at the given target; raises _Fail when the ratio falls below 1.01."""
        target = float(self.target)
        T = self.start_tension()
        e_a = np.zeros(self.model.n_dof)
        e_a[self.a] = 1.0
        try:
            self.target = T
            q = self.newton(q_at(T), 1.0, pinned, bordered=True, max_iterations=12, line_search=False)
            ratio, prev = 4.0, None
            while T > target:
                _, K, _, rank1 = self.evaluate(q, 1.0, pinned, True)
                try:
                    dq_du = -T * T * _solve(K, e_a, self.model.dense, rank1)
                except (np.linalg.LinAlgError, RuntimeError):
                    dq_du = np.zeros_like(q)
                curvature = 0.0  # (n,) d2q/du2 / 2 from the solution before the last one
                if prev is not None:
                    dp = 1.0 / prev[1] - 1.0 / T
                    curvature = (prev[0] - q - dq_du * dp) / dp**2
                while True:
                    T_next = max(target, T / ratio)
                    du = 1.0 / T_next - 1.0 / T
                    self.target = T_next
                    self.accept = 1.0 if T_next == target else 100.0
                    n0 = len(self.history)
                    try:
                        q_new = self.newton(q + dq_du * du + curvature * du**2, 1.0, pinned, bordered=True,
                                            max_iterations=8, line_search=False)
                    except _Fail:
                        ratio = float(np.sqrt(ratio))
                        if ratio < 1.01:
                            raise
                        continue
                    break
                if len(self.history) - n0 <= 3:
                    ratio = min(ratio * ratio, 1e3)
                prev = (q, T)
                q, T = q_new, T_next
            return q
        finally:
            self.target = target
            self.accept = 1.0

    def tension_loop(self, q: np.ndarray) -> np.ndarray:
        """Outer Newton on the adjustable pulley's slide offset s: equilibrium at fixed s inside,
        T(s) = target outside, with dT/ds from the equilibrium's sensitivity K_ff dq_f/ds = -K_fs."""
        m, a = self.model, self.a
        pinned = np.array([self.driver, a])
        q = self.continuation(q, pinned)
        tol_T = self.tension_tolerance()
        for it in range(self.opts.max_iterations):
            T, dT = m.mean_tension_and_gradient(q)
            g = T - self.target
            if abs(g) <= tol_T:
                return q
            _, K = m.equilibrium(q, 1.0)
            col = np.asarray(K[:, a]).ravel() if m.dense else K.getcol(a).toarray().ravel()
            col[pinned] = 0.0
            K = _pin(K, pinned, m.dense)
            try:
                dqf = _solve(K, -col, m.dense)
            except (np.linalg.LinAlgError, RuntimeError):
                dof = _null_dof(K, m.dense, m.dof_labels)
                raise _Fail("singular tangent stiffness in the tension iteration", abs(g) / tol_T, dof) from None
            slope = float(dT[a] + dT @ dqf)
            if not abs(slope) > 1e-12 * self.EA:
                raise _Fail(f"the span tension does not change when the adjustable pulley moves "
                            f"(dT/ds = {slope:.3g} N/m)",
                            abs(g) / tol_T, m.dof_labels[a])
            step = -g / slope
            for _ in range(40):
                q_try = q.copy()
                q_try[a] += step
                q_try += step * dqf
                try:
                    q_new = self.newton(q_try, 1.0, pinned)
                except _Fail:
                    step *= 0.5
                    continue
                T_new, _ = m.mean_tension_and_gradient(q_new)
                if T_new > 0.0:
                    break
                step *= 0.5
            else:
                raise _Fail(f"tension iteration {it + 1}: no equilibrium found near slide offset {q[a]:.6g} m",
                            abs(g) / tol_T, m.dof_labels[a])
            q = q_new
            self.history.append((abs(T_new - self.target) / tol_T, 1.0))
        raise _Fail(f"tension iteration did not converge in {self.opts.max_iterations} iterations",
                    abs(g) / tol_T, m.dof_labels[a])


def solve_static(system: System, options: StaticOptions, *, q0: np.ndarray | None = None,
                 budget: Budget | None = None) -> StaticResult:
    """Static equilibrium of the drive (raises SolverError naming step, residual and DOF).

    Tension mode "adjust": a bordered Newton on (equilibrium, T = target) from the linear axial
    predictor, which converges in one or two iterations for taut spans; if it stalls on spans that sag
    under their weight, a continuation in the tension target (`_Problem.tension_continuation`); if
    that fails too, an outer Newton on the slide offset around inner equilibrium solves with load
    stepping on the weight. Other modes: equilibrium with load stepping. q0: a start (n_dof,)
    instead of the predictor (warm start; the driver's rotation is held at q0's value); if Newton
    fails from it, the solve starts over as without it.

    One system, one layout: the joints keep the tangent points of `system.layout`, so a pulley that
    moves far meets its spans off tangent; `solve_static_on_solved_geometry` (what
    `pipeline.analyse` calls) lays the belt out again at the solved positions.
    """
    q, preload, hist, known = solve_equilibrium(system, options, q0=q0, known=True, budget=budget)
    return _result(system, q, preload, hist[:, 0], hist[:, 1], len(hist), system.driver_dof, known=known)


def solve_equilibrium(system: System, options: StaticOptions, *, q0: np.ndarray | None = None, known: bool = False,
                      budget: Budget | None = None):
    """The equilibrium of `solve_static` without its outputs: (q (n_dof,), spring preloads (n_dof,),
    Newton history (n_iter, 2) of (scaled residual, load factor)). For the re-lay passes, whose
    outputs only the last one needs. known: also what the solve evaluated at q that the outputs reuse
    ({"driver_torque", "mean_tension", "tangent"}, each present only if evaluated at q at full load; the
    tangent dr/dq of `System.equilibrium`, unpinned, which the modal analysis reuses; "joint": q on the
    joint coordinates, P(q)). budget: the
    residual evaluations the analysis may still spend (`Budget`; default: a fresh one for this solve)."""
    model = system
    prob = _Problem(system, options, budget)
    n = model.n_dof
    pinned = np.array([prob.driver])
    prob.keep_tangent = known
    try:
        q = None
        sagging = prob.adjust and prob.has_weight  # the continuation in the tension target may be needed
        if q0 is not None:
            q0 = np.array(q0, dtype=float)
            try:
                q = prob.newton(q0, 1.0, pinned, bordered=prob.adjust, stall=sagging)
            except _Fail:
                pass
        if q is not None:
            pass
        elif prob.adjust:
            def straight(T: float) -> np.ndarray:
                return _predictor(model, stretch_for_tension(T, prob.EA), prob.a, prob.driver)

            tried = q0
            q0 = straight(prob.target)
            if tried is None or not np.array_equal(tried, q0):  # (a re-lay pass's first start is this one)
                try:
                    q = prob.newton(q0, 1.0, pinned, bordered=True, max_iterations=8, stall=sagging)
                except _Fail:
                    q = None
            if q is None and sagging:
                try:  # sagging spans: continuation in the tension target
                    q = prob.tension_continuation(straight, pinned)
                except _Fail:
                    q = None
            if q is None:
                q = prob.tension_loop(q0)
        else:
            q = prob.continuation(np.zeros(n), pinned)
    except _Stop as fail:
        lam = getattr(fail, "lam", 1.0)
        step = f"residual evaluation {prob.budget.used + 1}" if isinstance(fail, _Exhausted) else f"load factor {lam:.4g}"
        raise SolverError(f"{fail} (residual scaled so that 1 means converged)", analysis="static",
                          step=step, residual=fail.err, item=fail.dof) from None
    _check_stops(model, q)
    if prob.adjust:  # the bearing spring's preload follows from the adjustable pulley's slide equation
        _check_travel(model, q)
        r, _ = model.equilibrium(q, tangent=False)
        prob.preload[prob.a] = r[prob.a]
    hist = np.array(prob.history).reshape(-1, 2)
    if not known:
        return q, prob.preload, hist
    seen: dict = {}
    q_l, lam_l, r_driver, T, K, p = prob.last
    if q_l is q:
        seen["joint"] = p
    if q_l is q and lam_l == 1.0:
        seen["driver_torque"] = r_driver + float(prob.preload[prob.driver])
        if T is not None:
            seen["mean_tension"] = T
        if K is not None:
            seen["tangent"] = K
    return q, prob.preload, hist, seen


def _check_travel(system: System, q: np.ndarray) -> None:
    """The tension step's travel of the adjustable pulley (from its given centre) within its slide_range."""
    ts = system.tension
    lim = ts.adjust_range
    if lim is None or ts.adjust_dof < 0 or system.dof_groups[ts.adjust_dof] != 2:  # arms: `_check_stops`
        return
    travel = system.layout.adjust_offset + float(q[ts.adjust_dof])
    span = max(abs(lim[0]), abs(lim[1]), 1e-3)
    if lim[0] - 1e-12 * span <= travel <= lim[1] + 1e-12 * span:
        return
    raise SolverError(
        f"tension.target = {ts.target:g} N needs pulley '{ts.adjust_name}' to travel {travel:.6g} m along its slide "
        f"(from its given centre), outside its slide_range [{lim[0]:g}, {lim[1]:g}] m; lower the target or "
        f"widen the slide_range", analysis="static", step="tension step",
        item=system.dof_labels[ts.adjust_dof])


def _check_slack(system: System, st: StaticResult) -> None:
    """A span in compression at equilibrium: the belt would go slack (it carries no compression; the
    model's bending stiffness holds it only numerically). A named failure, never a silent result."""
    T = st.span_tension
    if T.min() >= 0.0:  # (the common case: no span in compression at all)
        return
    lowest = T.min(axis=1)
    worst = int(lowest.argmin())
    if lowest[worst] >= -1e-6 * float(np.abs(T).max(initial=1.0)):
        return
    loads = " under the accessory torques" if system.loads is not None and np.any(system.loads) else ""
    raise SolverError(f"span {system.layout.span_name(worst)} is compressed ({T[worst].min():.4g} N){loads}: the belt "
                      f"goes slack there; raise the tension (tension.target or the tensioner spring) or lower the "
                      f"loads", analysis="static", step="slack check", residual=float(-T[worst].min()),
                      item=f"span {worst + 1} ({system.layout.span_name(worst)})")


def _check_stops(system: System, q: np.ndarray) -> None:
    """Every tensioner arm's equilibrium angle between its stops (arm_range)."""
    a = system.arms
    if a is None or a.stops is None:
        return

    for k, (lo, hi) in enumerate(a.stops.tolist()):
        if lo != lo:  # NaN: no stops
            continue
        phi = unwrap_near(float(a.angle[k] + q[a.dof[k]]), 0.5 * (lo + hi))
        if lo - 1e-12 <= phi <= hi + 1e-12:
            continue
        ts = system.tension
        why = (f"tension.target = {ts.target:g} N needs" if ts.adjust_dof == int(a.dof[k]) else
               "the static equilibrium puts")
        raise SolverError(f"{why} the arm of pulley '{a.names[k]}' at {phi:.6g} rad, outside its stops "
                          f"arm_range = [{lo:g}, {hi:g}] rad; change the target, the spring or the stops",
                          analysis="static", step="tension step" if ts.adjust_dof == int(a.dof[k]) else "equilibrium",
                          item=system.dof_labels[int(a.dof[k])])


def _result(model: System, q, preload, hist_r, hist_l, iterations, driver_dof, *, known: dict | None = None
            ) -> StaticResult:
    """The outputs at the solution q; known: values the solve already evaluated at q (see
    `solve_equilibrium`)."""
    lay = model.layout
    known = known or {}
    p = known["joint"] if "joint" in known else model.expand(q)
    hub, span_tension, T_mean = model.static_span_outputs(q, p=p, mean="mean_tension" not in known)
    if "driver_torque" in known:
        driver_torque = known["driver_torque"] - float(preload[driver_dof])
    else:
        driver_torque = float((model.equilibrium(q, tangent=False)[0] - preload)[driver_dof])
    if T_mean is None:
        T_mean = known["mean_tension"]
    a = lay.adjust_index
    if a is None:
        offset = 0.0
    elif lay.adjust_kind == "arm":
        offset = lay.adjust_offset + float(q[model.dofs.arm_dof[a]])
    else:
        offset = lay.adjust_offset + float(q[model.trans_dof[a][0]])

    n = lay.n
    arm_angle = np.full(n, np.nan)
    arm_torque, arm_free, pivot = arm_angle.copy(), arm_angle.copy(), np.full((n, 2), np.nan)
    if model.arms is not None:
        arms = model.arms
        for k, (j, spring, weight) in enumerate(model.arm_statics):
            d = int(arms.dof[k])
            arm_angle[j] = float(arms.angle[k] + q[d])
            if spring is not None:
                k_s = float(spring.stiffness[0, 0])
                free = float(spring.free[0]) if spring.free is not None else 0.0
                arm_torque[j] = -(k_s * (q[d] - free) - preload[d])  # the spring's torque on the arm
                arm_free[j] = arm_angle[j] + arm_torque[j] / k_s
            else:  # no spring: a constant preload torque (adjust mode), if any
                arm_torque[j] = float(preload[d])
            pivot[j] = -(hub[j] + weight)  # statics of arm + pulley: pivot + belt + weight = 0
    applied = np.zeros(n) if model.loads is None else model.loads[model.rot_dof]
    friction = model.pulley_friction
    mu_req = required_friction(span_tension, lay.wrap_angle)
    return StaticResult(
        q=q, spring_preload=preload, span_tension=span_tension, mean_tension=T_mean,
        hub_load=hub, pulley_center=known["pulley_center"] if "pulley_center" in known else model.pulley_centers(q, p=p),
        pulley_rotation=q[model.rot_dof],
        driver_torque=driver_torque, adjust_offset=offset,
        residual_history=np.array(hist_r), load_factor_history=np.array(hist_l), iterations=iterations,
        tension_mode=model.tension.mode, arm_angle=arm_angle, arm_torque=arm_torque, arm_free_angle=arm_free,
        pivot_reaction=pivot, applied_torque=applied, required_friction=mu_req,
        slip_margin=(slip_margin(mu_req, friction) if friction is not None and not np.isnan(friction).all()
                     else np.full(n, np.nan)))


# ------------------------------------------------------------------------------------ solved geometry
MAX_PASSES = 25


@dataclass(frozen=True, kw_only=True)
class SolvedDrive:
    """The static equilibrium on the solved geometry: the final system (laid out at the solved pulley
    positions) and its static result."""

    system: System
    static: StaticResult
    passes: int  # layouts solved on (the first included)
    solves: int  # static solves (prestrain iterations included)
    movement: np.ndarray  # (passes,) largest pulley displacement from its laid centre after each pass, m
    newton_iterations: int = 0  # Newton iterations of all passes and solves (failed attempts included)
    tangent: object = None  # dr/dq of `system.equilibrium` at static.q at full load, if the solve evaluated it there


def carried_reference(old, new, reference_length: np.ndarray) -> np.ndarray:
    """Span reference lengths (n,) on layout `new` of the belt whose spans had `reference_length` on
    layout `old`, the wraps unstretched: where a tangent point moves along its pulley by an arc
    R dpsi in the direction of belt travel, that much belt passes from the span onto the wrap (or
    back). The total, sum(reference lengths) + sum(arc lengths), is kept. Pulley rotations stay
    coordinates of the system (the joints slide the span ends along the tangent lines).

    Both tangent points of span s turn with its tangent line: their normals are +-(sin a_s, -cos a_s),
    so dpsi = a_s(new) - a_s(old) (wrapped to [-pi, pi)) at both ends, and with the signed radii
    rho = orientation x side x R the span leaves rho_s dpsi onto pulley s and takes rho_(s+1) dpsi
    from pulley s+1: reference_s - dpsi_s (rho_s - rho_(s+1))."""
    return np.array(_carried(old.span_angle.tolist(), new.span_angle.tolist(), _radius_steps(new),
                             reference_length.tolist(), new.span_name))


def _radius_steps(layout) -> list:
    """rho_s - rho_(s+1) (n,) of each span s, rho = orientation x side x radius (`carried_reference`)."""
    rho = (layout.orientation * layout.side_sign * layout.radius).tolist()
    return [rho[s] - rho[s + 1 - len(rho)] for s in range(len(rho))]


def _carried(old_angle: list, new_angle: list, radius_step: list, reference: list, span_name) -> list:
    """`carried_reference` on Python floats: lists (n,) of the old and new span angles, the spans'
    `_radius_steps` and the old reference lengths; span_name(s) names span s in the error. (A span
    whose angle is unchanged keeps its length: the formula's term is an exact 0 there.)"""
    out = [r if a == b else r - ((b - a + math.pi) % TWO_PI - math.pi) * d
           for a, b, d, r in zip(old_angle, new_angle, radius_step, reference)]
    total = sum(out)  # (NaN if any is: min() of a list skips a NaN after the first)
    if not (min(out) > 0.0 and total == total):
        s = min(range(len(out)), key=lambda k: out[k] if out[k] == out[k] else -math.inf)
        raise SolverError(f"span {span_name(s)} has no belt left at the solved pulley positions (reference "
                          f"length {out[s]:.3g} m)", analysis="static", step="re-lay", item=f"span {s + 1}")
    return out


def _meet_prestrain(build, layout, lam: float, free: np.ndarray, options: StaticOptions, slope: float | None,
                    budget: Budget | None = None):
    """Secant on the spans' uniform prestrain stretch lam until the static mean tension equals the
    target (the pulleys free on their bearings). Returns (system, static, lam, slope, solves)."""
    system = build(layout, lam, free)
    target = float(system.tension.target)
    EA = system.EA
    tol_T = options.tolerance * abs(target) + 100 * np.finfo(float).eps * EA
    if slope is None:
        slope = 0.5 * EA * (3.0 * lam**2 - 1.0)  # rigid supports
    prev = None
    for it in range(options.max_iterations):
        if it:
            system = build(layout, lam, free)
        st = solve_static(system, options, budget=budget)
        g = st.mean_tension - target
        if abs(g) <= tol_T:
            return system, st, lam, slope, it + 1
        if prev is not None and lam == prev[0]:  # no representable step left (the stretch is at 1)
            raise SolverError(
                f'tension.mode = "prestrain" cannot reach tension.target = {target:g} N: the mean span tension is '
                f"{st.mean_tension:.6g} N at span stretch {lam:.12g}" + (" (unstretched spans: the weight and the "
                f"supports alone give it)" if lam == 1.0 else "") + '; lower the target or use mode = "adjust"',
                analysis="static", step=f"prestrain iteration {it + 1}", residual=abs(g) / tol_T, item="tension.target")
        if prev is not None:
            secant = (g - prev[1]) / (lam - prev[0])
            if not (np.isfinite(secant) and secant > 1e-9 * EA):
                raise SolverError(
                    f'tension.mode = "prestrain" cannot reach tension.target = {target:g} N: the mean span tension '
                    f"({st.mean_tension:.6g} N at span stretch {lam:.9g}) does not grow with the prestrain "
                    f"(dT/dstretch = {secant:.3g} N); a support gives way without limit", analysis="static",
                    step=f"prestrain iteration {it + 1}", residual=abs(g) / tol_T, item="tension.target")
            slope = secant
        prev = (lam, g)
        new = lam - g / slope
        lam = new if new > 1.0 else 1.0 + 0.5 * (lam - 1.0)
    raise SolverError(f'tension.mode = "prestrain": the mean span tension did not reach tension.target = '
                      f"{target:g} N in {options.max_iterations} prestrain iterations (last {st.mean_tension:.9g} N)",
                      analysis="static", step="prestrain iteration", residual=abs(g) / tol_T, item="tension.target")


def torque_split(layout, loads: np.ndarray | None, rot_dof: np.ndarray, driver: int) -> np.ndarray:
    """(n,) span tensions relative to the span leaving the driver (its pulley index) that the static
    accessory torques ask for on a rigid belt: the belt's torque on pulley j is rho_j (T_j - T_(j-1)), rho = orientation x
    side x radius, so every other pulley has T_j = T_(j-1) - tau_j / rho_j (the driver reacts the rest)."""
    n = layout.n
    if loads is None:
        return np.zeros(n)
    split = [0.0] * n  # (floats: a few pulleys)
    rho = (layout.orientation * layout.side_sign * layout.radius).tolist()
    tau = loads[rot_dof].tolist()
    for i in range(1, n):
        j = (driver + i) % n
        split[j] = split[j - 1] - tau[j] / rho[j]
    return np.array(split)


def _conserved_tension(total_length: float, split: list, reference: list, EA: float) -> list:
    """(n,) span tensions T_ref + split of a belt whose spans' reference lengths are `reference` (n,)
    (`carried_reference`: the wraps unstretched) on a path whose spans are total_length long together,
    its pulleys turning freely: the rotations slide the span ends along the tangent lines (the joints),
    which moves chord between neighbouring spans and keeps their sum, so
    sum_s lambda(T_s) reference_s = sum_s L_s (Newton on T_ref). Lists of Python floats (numpy calls
    on 2-12 numbers cost more than the arithmetic)."""

    L, ref, sp = total_length, reference, split
    total = sum(ref)
    T_ref = EA * (L / total - 1.0) - sum(map(mul, ref, sp)) / total  # the start: lambda = 1 + x,
    x = [(T_ref + s) / EA for s in sp]
    T_ref += 1.5 * EA * sum([r * v * v for r, v in zip(ref, x)]) / total  # then 1 + x - 3/2 x^2 (one step)
    x = [(T_ref + s) / EA for s in sp]
    lam = ([stretch_start(v) for v in x] if max(map(abs, x)) < 0.05 else
           [stretch_for_tension(T_ref + s, EA) for s in sp])
    half = 0.5 * EA
    for _ in range(50):  # Newton on T_ref, each stretch first stepped to its span's tension (one Newton step)
        stepped, worst, length, compliance = [], 0.0, 0.0, 0.0  # (one pass: lists of 7 cost their loops' overhead)
        for y, s, r in zip(lam, sp, ref):
            slope = half * (3.0 * y * y - 1.0)  # dT/dlambda
            d = (half * (y * y * y - y) - (T_ref + s)) / slope
            y -= d
            stepped.append(y)
            if abs(d) > worst:
                worst = abs(d)
            length += y * r
            compliance += r / slope
        lam = stepped
        step = (length - L) / compliance
        T_ref -= step
        # done when the stretches were exact (Newton on the cubic leaves about 1.5 d^2 after a step d, below
        # 2e-16 for d <= 1e-8) and what T_ref still lacks is below 1e-12 EA: Newton leaves c step^2 / EA after
        # a step, c = |g''| EA / (2 g') <= 6 lambda_max / (3 lambda_min^2 - 1)^2 (1.5 at lambda = 1)
        if worst <= 1e-8:
            lo = min(lam)
            h = 3.0 * lo * lo - 1.0  # (a float's ** raises on overflow)
            if abs(step) <= 1e-12 * EA or (h > 0.1 and 6.0 * max(lam) * step * step <= 1e-12 * EA * EA * h * h):
                break
    return [T_ref + s for s in sp]


def _predicted_centers(system: System, anchored: set, fit, tol_x: float, span_tension) -> np.ndarray:
    """Pulley centres (n, 2) of the drive on a rigid belt whose span tensions `span_tension(angles,
    lengths)` (lists (n,) of a layout's span angles and lengths -> list (n,)) gives (the target or the
    belt's length, split by the accessory torques): the adjustable pulley where `fit(centers)` places
    it (mode "adjust"), every spring-supported pulley deflected by its bearing springs under the belt's
    pull T_j t_j - T_(j-1) t_(j-1) of that layout and the weight on its DOFs (`gravity_force`, the
    pulley's and its share of the belt's), every sprung tensioner arm (but the adjusting one) turned
    until its spring balances the moment of that pull about its pivot (secant; where nothing else
    moves with the arm, its iterates lay out only the arm pulley's spans, `geometry.MovingPulley`).
    A fixed point over layouts (cheap geometry); the static passes correct what it leaves out (sag,
    bending, the arms' weight)."""

    lay0 = system.layout
    place = fit if fit is not None else (lambda c: relay(lay0, c, check=False))  # checked where laid (lay_out)
    k_diag = np.asarray(system.linear_matrix().diagonal()).ravel() if anchored else None
    arms = []  # (pulley, pivot, length, stiffness, layout angle, free angle) of each sprung arm it turns
    if system.arms is not None:
        a = system.arms
        for k, dof in enumerate(a.dof):
            spring = system.arm_spring(dof)
            if int(dof) == system.tension.adjust_dof or spring is None:
                continue
            j = a.pulleys[k]
            free = float(spring.free[0]) if spring.free is not None else 0.0
            arms.append((j, a.pivot[k], float(a.length[k]), float(spring.stiffness[0, 0]), float(a.angle[k]),
                         float(a.angle[k]) + free))
    centers = lay0.center.copy()
    if not anchored and not arms and fit is not None:  # nothing deflects: the fit alone places the pulleys
        return fit(centers).center

    def pull(lay) -> np.ndarray:
        f = np.array(span_tension(lay.span_angle.tolist(), lay.span_length.tolist()))[:, None] * lay.span_direction
        return f - np.roll(f, 1, axis=0)  # (span j - 1 arrives at pulley j)

    def arm_moment(j: int, pv: np.ndarray, length: float, k_s: float, phi_f: float):
        """The moment about the pivot on arm pulley j at arm angle phi (spring and belt pull)."""
        if fit is not None:  # the fit moves the adjustable pulley with it: whole layouts
            def moment(phi: float) -> float:
                c = centers.copy()
                c[j] = pv + length * np.array([np.cos(phi), np.sin(phi)])
                r, f = c[j] - pv, pull(place(c))[j]
                return float(r[0] * f[1] - r[1] * f[0]) - k_s * (phi - phi_f)
            return moment
        path = MovingPulley(lay0 if not moved else place(centers), j)
        px, py, i = float(pv[0]), float(pv[1]), path.prev

        def moment(phi: float) -> float:  # only pulley j moves: its two spans in floats
            cs, sn = math.cos(phi), math.sin(phi)
            angle, span_length, _ = path.at(px + length * cs, py + length * sn)
            T = span_tension(angle, span_length)
            fx = T[j] * math.cos(angle[j]) - T[i] * math.cos(angle[i])
            fy = T[j] * math.sin(angle[j]) - T[i] * math.sin(angle[i])
            return length * (cs * fy - sn * fx) - k_s * (phi - phi_f)
        return moment

    moved = False  # (centers still lay0's)
    for _ in range(50):
        for j, pv, length, k_s, phi_ref, phi_f in arms:  # each arm's balance, the other pulleys where they are
            moment = arm_moment(j, pv, length, k_s, phi_f)
            phi0 = pivot_angle(centers[j], pv)
            phi0 += 2.0 * np.pi * round((phi_ref - phi0) / (2.0 * np.pi))  # the layout's branch of the angle
            phi1 = phi0 + 1e-4
            m0, m1 = moment(phi0), moment(phi1)
            for _ in range(30):
                if m1 == m0:
                    break
                phi0, phi1, m0 = phi1, phi1 - m1 * (phi1 - phi0) / (m1 - m0), m1
                if abs(phi1 - phi0) * length <= tol_x:
                    break
                m1 = moment(phi1)
            centers[j] = pv + length * np.array([np.cos(phi1), np.sin(phi1)])
            moved = True
        if not anchored and len(arms) == 1 and fit is None:  # the one arm balanced, nothing else moves: done
            break
        lay = place(centers)
        force = pull(lay)
        new = lay.center.copy()
        for j, (dofs, dirs) in enumerate(zip(system.trans_dof, system.trans_dir)):
            if any(k in anchored for k in dofs):
                new[j] = lay0.center[j]
            for k, v in zip(dofs, dirs):
                if k in anchored and k_diag[k] > 0.0:
                    new[j] = new[j] + v * (float(force[j] @ v) + float(system.gravity_force[k])) / k_diag[k]
        done = float(np.abs(new - centers).max()) <= tol_x
        centers = new
        if done:
            break
    return centers


def warm_start(system: System, previous: System, q: np.ndarray) -> np.ndarray:
    """A start for the static solve on a re-laid system: the previous solution's pulley rotations, the
    moved supports at their new layout position (0), and each span's previous shape carried over: its
    nodes moved by the linear interpolation of its end nodes' moves (a sagging span keeps its sag, a
    taut one stays straight between its new end nodes), the slopes kept."""
    q0 = np.zeros(system.n_dof)
    q0[system.rot_dof] = q[previous.rot_dof]
    old = previous.belt.element_coordinates(previous.expand(q))
    new = system.belt.element_coordinates(system.expand(q0))  # the end nodes where q0 puts them
    model = system.belt
    for s_, els in enumerate(model.span_elements):
        n_e = len(els)
        if not n_e:  # a spring span: no nodes of its own
            continue
        frac = (np.arange(n_e + 1) / n_e)[:, None]
        nodes = np.vstack([old[els, 0:4], old[els[-1], 4:8][None]])  # (n_e + 1, 4): r, r' of each node
        da, db = new[els[0], 0:2] - nodes[0, 0:2], new[els[-1], 4:6] - nodes[-1, 0:2]
        nodes[:, 0:2] += (1.0 - frac) * da + frac * db
        e0 = np.vstack([model.e0[els, 0:4], model.e0[els[-1], 4:8][None]])
        d = nodes - e0
        # span DOFs: the first node's slope, the interior nodes (r, r'), the last node's slope
        q0[system.dofs.span_slices[s_]] = np.concatenate([d[0, 2:4], d[1:-1].ravel(), d[-1, 2:4]])
    return q0


def solve_static_on_solved_geometry(system: System, build, options: StaticOptions, *,
                                    max_passes: int = MAX_PASSES) -> SolvedDrive:
    """Static equilibrium with the belt laid out at the solved pulley positions.

    `system` is laid out on the L0 fit (`build_system`); build(layout, prestrain_stretch, spring_free)
    builds the same drive on another layout (see `build_system`). A pulley that moves in the static
    solve (the adjustable pulley's tension travel, a bearing's deflection) leaves its spans meeting it
    off tangent (the joints keep the tangent points of the layout), so the layout is laid anew at the
    solved centres (`geometry.relay`: tangent points, spans and wraps recomputed), the system rebuilt
    and solved again, until no pulley moves more than tolerance x (shortest span) from its laid centre.
    The first layout is predicted (`_predicted_centers`: the drive under a uniform tension, pure
    geometry), and from the third pass on the next centres are extrapolated (Aitken) when the passes
    contract steadily: one pass without weight, two or three with it.

    The reference (stress-free) state of the re-laid spans, by tension mode:
    - "adjust" (and no target with an adjustable pulley): the belt of undeformed length L0 lies on the
      spans and the wraps, the wraps unstretched (as in the L0 geometry of DESIGN section 2, where the
      spans are stress-free and moving the pulley stretches the spans only): `carried_reference` moves
      belt between span and wrap where a tangent point moves, so the spans' reference lengths sum to
      L0 - sum(R_j wrap_j) on every layout, and the pulley rotations stay what they were.
    - "prestrain": a uniform span stretch, iterated (secant, `_meet_prestrain`) until the static mean
      tension equals the target with every pulley free on its bearing.
    - no target, no adjustable pulley: the belt of length L0 stretched uniformly onto the new path.
    Bearing springs stay anchored where they were relaxed on the L0 fit (spring_free); the adjustable
    pulley's spring in mode "adjust" carries the preload its slide equation asks for, as before.
    """

    ts = system.tension
    lay0 = lay = system.layout
    d = system.dofs
    n_dof = d.n
    arm_of = {} if system.arms is None else {int(s_): k for k, s_ in enumerate(system.arms.slot)}
    trans = np.array([k for dofs in d.trans_dof for k in dofs if (dofs[0] if dofs else -1) not in arm_of],
                     dtype=np.int64)  # spring-supported translations (an arm pulley's offsets are not)
    anchored = set((trans[trans != ts.adjust_dof] if ts.mode == "adjust" else trans).tolist())
    conserve = ts.mode in ("adjust", "spring") or (ts.mode == "geometry" and lay.adjust_index is not None)
    moving = bool(trans.size) or system.arms is not None
    prestrain = ts.mode == "prestrain" and ts.target is not None
    EA = float(system.EA)
    tol_x = options.tolerance * float(lay0.span_length.min())

    def lay_out(old: Layout, centers: np.ndarray, ref_old: np.ndarray, step: str):
        """(layout, spring_free, system or None) at `centers`, the belt carried over from `old`."""
        a = old.adjust_index
        if a is None:
            offset = None
        elif old.adjust_kind == "arm":  # the further turn of the arm about its pivot
            pv = system.arms.pivot[arm_of[d.trans_dof[a][0]]]
            turn = pivot_angle(centers[a], pv) - pivot_angle(old.center[a], pv)
            offset = old.adjust_offset + float((turn + np.pi) % (2 * np.pi) - np.pi)
        else:
            offset = old.adjust_offset + float((centers[a] - old.center[a]) @ d.trans_dir[a][0])
        try:
            new = relay(old, centers, adjust_offset=offset)
        except GeometryError as exc:
            j = int(np.argmax(np.linalg.norm(centers - old.center, axis=1)))
            raise SolverError(f"no belt path through the solved pulley positions: {exc}", analysis="static",
                              step=step, item=f"pulley {old.names[j]}") from None
        free = np.zeros(n_dof)  # the springs stay relaxed where they were on the L0 fit
        for j, (dofs, dirs) in enumerate(zip(d.trans_dof, d.trans_dir) if anchored else ()):
            for k, v in zip(dofs, dirs):
                if k in anchored:
                    free[k] = -float((centers[j] - lay0.center[j]) @ v)
        if system.arms is not None:  # an arm spring without a free angle: relaxed at its L0-fit angle
            for k, dof in enumerate(system.arms.dof):
                if int(dof) == ts.adjust_dof:
                    continue  # the tension step sets its preload
                j = system.arms.pulleys[k]
                pv = system.arms.pivot[k]
                turn = pivot_angle(lay0.center[j], pv) - pivot_angle(centers[j], pv)
                free[int(dof)] = float((turn + np.pi) % (2 * np.pi) - np.pi)
        if conserve:
            return new, free, build(new, new.span_length / carried_reference(old, new, ref_old), free)
        if prestrain:
            return new, free, None  # built by _meet_prestrain
        return new, free, build(new, None, free)

    free = np.zeros(n_dof)
    warm = None
    lam_p, slope = float(system.belt.prestrain_stretch), None
    ref0 = system.belt.reference_length
    material = float(ref0.sum() + lay0.arc_length.sum())  # L0, wraps unstretched
    split = torque_split(lay0, system.loads, d.rot_dof, system.driver)
    sp = split.tolist()
    if ts.target is not None:
        def span_tension(angle: list, length: list) -> list:  # the target as the length-weighted mean, split by
            mean = float(ts.target) - sum(x * y for x, y in zip(length, sp)) / sum(length)  # the torques
            return [mean + y for y in sp]
    elif conserve and ts.mode != "adjust":
        angle0, ref0_, step0 = lay0.span_angle.tolist(), ref0.tolist(), _radius_steps(lay0)

        def span_tension(angle: list, length: list) -> list:  # what the belt's length gives on that path
            return _conserved_tension(sum(length), sp, _carried(angle0, angle, step0, ref0_, lay0.span_name), EA)
    else:
        span_tension = None
    predict = span_tension is not None and (moving or ts.mode == "adjust")
    if predict:  # predicted first layout
        fit = None
        if ts.mode == "adjust":
            lam_T = stretch_for_tension(float(ts.target), EA)
            j = lay0.adjust_index

            pivot = None if lay0.adjust_kind != "arm" else system.arms.pivot[arm_of[d.trans_dof[j][0]]]

            def fit(centers):  # the adjustable pulley where spans at the target stretch fit
                lay_f = fit_adjustable(centers, lay0.radius, lay0.side_sign, lay0.names, index=j,
                                       direction=d.trans_dir[j][0], target_length=lam_T * material,
                                       arc_weight=lam_T, orientation=lay0.orientation, pivot=pivot,
                                       base=lay0 if np.array_equal(centers, lay0.center) else None)
                if pivot is not None:  # the turn counts from the drawn arm angle, as on the L0 fit
                    lay_f = Layout(**{**lay_f.__dict__, "adjust_offset": lay0.adjust_offset + lay_f.adjust_offset})
                return lay_f
        try:
            centers = _predicted_centers(system, anchored, fit, tol_x, span_tension)
            lay, free, built = lay_out(lay0, centers, system.belt.reference_length, "prediction")
            if prestrain:
                lam_p = stretch_for_tension(float(ts.target), EA)
            else:
                # started with the pulleys turned to the predicted span tensions
                T = span_tension(lay.span_angle.tolist(), lay.span_length.tolist())
                warm = _predictor(built, np.array([stretch_for_tension(t, EA) for t in T]), ts.adjust_dof,
                                  built.driver_dof)
                system = built
        except (GeometryError, SolverError, ArithmeticError, ValueError, np.linalg.LinAlgError):
            lay, free, warm = lay0, np.zeros(n_dof), None  # no prediction: start from the L0 fit
    if hasattr(system, "full"):  # a deferred build (pipeline.analyse): solved on the L0 fit after all
        system = system.full()
    prev_step = None
    movement: list[float] = []
    solves = iterations = 0
    budget = Budget.of(options)  # over all passes and solves
    for p in range(1, max_passes + 1):
        if prestrain:
            system, st, lam_p, slope, k = _meet_prestrain(build, lay, lam_p, free, options, slope, budget)
            solves += k
            q_p, known = st.q, {}
            iterations += st.iterations  # (the last prestrain solve's)
        else:
            q_p, preload, hist, known = solve_equilibrium(system, options, q0=warm, known=True, budget=budget)
            solves += 1
            iterations += len(hist)
        solved_centers = system.pulley_centers(q_p, p=known.get("joint"))
        step = solved_centers - lay.center
        movement.append(float(np.sqrt((step * step).sum(axis=1)).max(initial=0.0)))  # (the largest |step|)
        if not moving or movement[-1] <= tol_x:
            if not prestrain:
                st = _result(system, q_p, preload, hist[:, 0], hist[:, 1], len(hist), system.driver_dof,
                             known={**known, "pulley_center": solved_centers})
            _check_slack(system, st)
            return SolvedDrive(system=system, static=st, passes=p, solves=solves, movement=np.array(movement),
                               newton_iterations=iterations, tangent=None if prestrain else known.get("tangent"))
        # the next layout: at the solved centres, extrapolated (Aitken) where the passes contract steadily
        centers = solved_centers
        if prev_step is not None:
            rho = float(np.vdot(step, prev_step) / np.vdot(prev_step, prev_step))
            cos = float(np.vdot(step, prev_step) / (np.linalg.norm(step) * np.linalg.norm(prev_step)))
            if abs(rho) < 0.5 and abs(cos) > 0.9:  # steps along one line, shrinking (or alternating)
                centers = centers + rho / (1.0 - rho) * step
                if system.arms is not None:  # an arm pulley stays on its circle about the pivot
                    for k in range(len(system.arms.dof)):
                        j = system.arms.pulleys[k]
                        pv = system.arms.pivot[k]
                        r = centers[j] - pv
                        centers[j] = pv + r * (np.hypot(*(lay0.center[j] - pv)) / np.hypot(*r))
        prev_step = step
        ref_old = system.belt.reference_length
        prev_system, prev_q = system, q_p
        lay, free, built = lay_out(lay, centers, ref_old, f"re-lay pass {p}")
        if prestrain:
            lam_p = float(lay.span_length.sum() / ref_old.sum())
        else:
            system = built
            warm = warm_start(system, prev_system, prev_q)
    j = int(np.argmax(np.linalg.norm(step, axis=1)))
    raise SolverError(f"the solved geometry did not settle in {max_passes} re-lay passes: pulley "
                      f"'{lay.names[j]}' still moves {movement[-1]:.3g} m from its laid centre "
                      f"(allowed {tol_x:.3g} m)", analysis="static", step=f"re-lay pass {max_passes}",
                      item=f"pulley {lay.names[j]}")
