"""The static equations of one drive on one layout and their Newton solve: the linear axial
predictor, the residual scales (err <= 1 means converged), the evaluation budget, Newton with line
search, load stepping, the continuation in the tension target and the bordered tension step
(`solve_static`, `solve_equilibrium`). The package docstring (`beltdyn.analysis.static`) gives the
equations."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from beltdyn.analysis.static.result import StaticResult, check_stops, check_travel, static_result
from beltdyn.config import StaticOptions
from beltdyn.errors import SolverError
from beltdyn.model.barlaw import axial_force, stretch_for_tension
from beltdyn.model.dofs import DOF_GROUPS
from beltdyn.model.system import System


def predictor(system: System, stretch: float | np.ndarray, adjust_dof: int, driver_dof: int) -> np.ndarray:
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
    # the normal equations: a few unknowns, a start for Newton (SVD least squares if singular)
    q = np.zeros(system.n_dof)
    if len(unknowns):  # (at least the non-driver pulleys' rotations)
        try:
            q[unknowns] = np.linalg.solve(A.T @ A, A.T @ target)
        except np.linalg.LinAlgError:
            q[unknowns] = np.linalg.lstsq(A, target, rcond=None)[0]
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
    if not np.isfinite(x).all():
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
        if d.rotor_dof is not None:  # a decoupler's rotor: a torque row like its pulley's
            on = d.rotor_dof >= 0
            lever[d.rotor_dof[on]] = system.layout.radius[on]
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
            S = float(np.abs(axial_force(lam, EA)).max(initial=0.0))
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
    return static_result(system, q, preload, hist[:, 0], hist[:, 1], len(hist), system.driver_dof, known=known)


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
                return predictor(model, stretch_for_tension(T, prob.EA), prob.a, prob.driver)

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
    check_stops(model, q)
    if prob.adjust:  # the bearing spring's preload follows from the adjustable pulley's slide equation
        check_travel(model, q)
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


