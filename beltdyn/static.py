"""Nonlinear static equilibrium: Newton with load stepping and line search.

Residual (reduced coordinates q, DESIGN section 2, paper Eq. 24 without inertia):
    R(q) = f_int(q) + k_s q - p - lambda f_g,
f_int the belt's internal force (Eqs. 14, 17) mapped through the joints, k_s the bearing springs
(Eq. 21) with preload p, f_g the weight (Eq. 8), lambda the load factor. The driver pulley's rotation
is held (it reacts the applied torques and removes the belt's rigid rotation). With tension mode
"adjust" the equation of the adjustable pulley's slide is replaced by  T(q) - T_target = 0,  T the
length-weighted mean true axial force of the spans: moving the pulley sets the tension and the
bearing spring's preload follows from the slide equation afterwards.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import DriveConfig
from .errors import ConfigError, SolverError
from .geometry import Layout, layout_from_config
from .model import DriveModel, build_model, stretch_for_tension
from . import ancf


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


def model_from_config(cfg: DriveConfig, layout: Layout | None = None) -> DriveModel:
    """Geometry + model, with the reference state that the tension mode asks for."""
    layout = layout or layout_from_config(cfg)
    target = cfg.tension.target
    if target is not None and cfg.tension.mode == "prestrain":
        lam = stretch_for_tension(target, cfg.belt.EA)
    elif target is None and cfg.adjustable_index is None:
        lam = layout.belt_length / cfg.belt.length  # the belt of length L0 stretched onto the path
        if lam < 1.0:
            raise ConfigError(
                f"the belt is {cfg.belt.length - layout.belt_length:.6g} m longer than its path "
                f"({layout.belt_length:.6g} m): it is slack; set tension.target or make a pulley adjustable",
                file=cfg.source, key="belt.length")
    else:
        lam = 1.0
    return build_model(cfg, layout, prestrain_stretch=lam)


def _predictor(model: DriveModel, stretch: float, adjust_dof: int, driver_dof: int) -> np.ndarray:
    """Linear axial estimate: rotations and the adjustable slide that stretch every span by `stretch`.

    Span elongation d_s = (dr_end - dr_start) . t_s is linear in the pulley DOFs; solve A x = (stretch-1) L_s
    for the non-driver rotations and the slide, then lay the nodes on the straight chords.
    """
    lay = model.layout
    n = lay.n
    unknowns = [int(model.rot_dof[j]) for j in range(n) if int(model.rot_dof[j]) != driver_dof] + [adjust_dof]
    col = {d: i for i, d in enumerate(unknowns)}
    A = np.zeros((n, len(unknowns)))
    t = model.reference_direction
    ends = []
    for s in range(n):
        e_first, e_last = model.span_elements[s][0], model.span_elements[s][-1]
        for el, rows, sign in ((e_first, slice(0, 2), -1.0), (e_last, slice(4, 6), 1.0)):
            for k, dof in enumerate(model.idx[el]):
                if dof in col:
                    A[s, col[dof]] += sign * float(model.T[el, rows, k] @ t[s])
        ends.append((e_first, e_last))
    target = (stretch - 1.0) * model.reference_length
    x = np.linalg.lstsq(A, target, rcond=None)[0]
    q = np.zeros(model.n_dof)
    q[unknowns] = x
    # Straight chords between the moved end nodes.
    e = model.element_coordinates(q)
    n_e = len(model.span_elements[0])
    for s, (e_first, e_last) in enumerate(ends):
        a, b = e[e_first, 0:2], e[e_last, 4:6]
        grad = (b - a) / model.reference_length[s]
        sl = model.span_dof_slices[s]
        block = np.zeros(sl.stop - sl.start)
        block[0:2] = grad - model.e0[e_first, 2:4]
        for node in range(1, n_e):
            x_ref = model.e0[model.span_elements[s][node], 0:2]
            block[2 + 4 * (node - 1): 4 + 4 * (node - 1)] = a + (b - a) * node / n_e - x_ref
            block[4 + 4 * (node - 1): 6 + 4 * (node - 1)] = grad - model.e0[model.span_elements[s][node], 2:4]
        block[-2:] = grad - model.e0[e_last, 6:8]
        q[sl] = block
    return q


def _solve(K, rhs: np.ndarray, dense: bool) -> np.ndarray:
    if dense:
        return np.linalg.solve(K, rhs)
    from scipy.sparse.linalg import spsolve

    with np.errstate(all="ignore"):
        x = spsolve(K.tocsc(), rhs)
    if not np.all(np.isfinite(x)):
        raise np.linalg.LinAlgError("singular matrix")
    return x


def _null_dof(K, dense: bool, free: np.ndarray, labels: tuple[str, ...]) -> str:
    """Label of the DOF with the largest share of the (near-)null vector of K."""
    Kd = K if dense else K.toarray()
    Kd = 0.5 * (Kd + Kd.T)
    w, v = np.linalg.eigh(Kd)
    vec = v[:, int(np.argmin(np.abs(w)))]
    return labels[int(free[int(np.argmax(np.abs(vec)))])]


class _Fail(Exception):
    """A failed Newton solve: message, scaled residual, DOF label at fault."""

    def __init__(self, message: str, err: float, dof: str) -> None:
        super().__init__(message)
        self.err, self.dof = err, dof


def _submatrix(K, rows: np.ndarray, cols: np.ndarray, dense: bool):
    return K[np.ix_(rows, cols)] if dense else K[rows][:, cols]


class _Problem:
    """The static equations of one drive: residual, Jacobian and Newton with line search.

    Residuals are scaled by the allowed residual, tolerance * force scale + a round-off floor
    (eps_GL = (r'.r' - 1)/2 loses ~machine epsilon, times EA, summed over elements), so that
    err <= 1 means converged.
    """

    def __init__(self, cfg: DriveConfig, model: DriveModel) -> None:
        self.model, self.opts = model, cfg.static
        self.target = cfg.tension.target
        self.adjust = self.target is not None and cfg.tension.mode == "adjust"
        self.driver = int(model.rot_dof[cfg.driver_index])
        self.a = model.trans_dof[cfg.adjustable_index][0] if self.adjust else -1
        self.preload = np.zeros(model.n_dof)
        self.noise = 1e3 * np.finfo(float).eps * float(model.elements.EA.max()) * np.sqrt(model.elements.n_elem)
        self.history: list[tuple[float, float]] = []
        self.has_load = bool(np.any(model.gravity_force != 0.0))

    def tension_tolerance(self) -> float:
        """Allowed error of the mean tension: relative tolerance + round-off of EA eps (~EA * eps)."""
        return self.opts.tolerance * abs(self.target) + 100 * np.finfo(float).eps * float(self.model.elements.EA.max())

    def allowed(self, lam: float) -> float:
        scale = max(abs(self.target) if self.target else 0.0,
                    float(np.abs(lam * self.model.gravity_force).max(initial=0.0)),
                    1e-9 * float(self.model.elements.EA.max()))
        return self.opts.tolerance * scale + self.noise

    def evaluate(self, q: np.ndarray, lam: float, free: np.ndarray, bordered: bool):
        """Scaled residual on `free`, its Jacobian, and err = max|R| / allowed."""
        m = self.model
        f, K = m.force_and_tangent(q)
        R = f - self.preload - lam * m.gravity_force
        if bordered:  # the slide equation of the adjustable pulley becomes T(q) = target
            T, dT = m.mean_tension_and_gradient(q)
            R[self.a] = T - self.target
            if m.dense:
                K = K.copy()
                K[self.a, :] = dT
            else:
                from scipy.sparse import csr_matrix, diags

                keep = np.ones(m.n_dof)
                keep[self.a] = 0.0
                row = csr_matrix((dT, (np.full(m.n_dof, self.a), np.arange(m.n_dof))), shape=K.shape)
                K = (diags(keep) @ K + row).tocsr()
        Rf = R[free]
        scaled = np.abs(R) / self.allowed(lam)
        if bordered:
            scaled[self.a] = abs(R[self.a]) / self.tension_tolerance()
        return Rf, _submatrix(K, free, free, m.dense), float(scaled[free].max(initial=0.0))

    def newton(self, q: np.ndarray, lam: float, free: np.ndarray, *, bordered: bool = False,
               max_iterations: int | None = None) -> np.ndarray:
        m = self.model
        labels = m.dof_labels
        n_max = self.opts.max_iterations if max_iterations is None else max_iterations
        R, K, err = self.evaluate(q, lam, free, bordered)
        for it in range(n_max):
            if err <= 1.0:
                return q
            try:
                dq = _solve(K, -R, m.dense)
            except (np.linalg.LinAlgError, RuntimeError):
                dof = _null_dof(K, m.dense, free, labels)
                raise _Fail(f"singular tangent stiffness in Newton iteration {it + 1} "
                            f"(no stiffness against a motion of '{dof}')", err, dof) from None
            alpha = 1.0
            for _ in range(12):
                q_try = q.copy()
                q_try[free] += alpha * dq
                R_t, K_t, err_t = self.evaluate(q_try, lam, free, bordered)
                if np.isfinite(err_t) and (err_t < err * (1.0 - 1e-4 * alpha) or err_t <= 1.0):
                    break
                alpha *= 0.5
            else:
                raise _Fail(f"line search failed in Newton iteration {it + 1}", err,
                            labels[int(free[int(np.argmax(np.abs(R)))])])
            q, R, K, err = q_try, R_t, K_t, err_t
            self.history.append((err, lam))
        if err <= 1.0:
            return q
        raise _Fail(f"Newton did not converge in {n_max} iterations", err,
                    labels[int(free[int(np.argmax(np.abs(R)))])])

    def continuation(self, q: np.ndarray, free: np.ndarray, *, bordered: bool = False) -> np.ndarray:
        """Load stepping on the weight, halving the increment on failure."""
        if not self.has_load:
            return self.newton(q, 1.0, free, bordered=bordered)
        lam_done, dlam = 0.0, 1.0 / self.opts.load_steps
        while lam_done < 1.0:
            lam = min(1.0, lam_done + dlam)
            try:
                q = self.newton(q, lam, free, bordered=bordered)
            except _Fail as fail:
                if dlam < 1.0 / 1024:
                    fail.lam = lam  # type: ignore[attr-defined]
                    raise
                dlam *= 0.5
                continue
            lam_done, dlam = lam, 2.0 * dlam
        return q

    def tension_loop(self, q: np.ndarray) -> np.ndarray:
        """Outer Newton on the adjustable pulley's slide offset s: equilibrium at fixed s inside,
        T(s) = target outside, with dT/ds from the equilibrium's sensitivity K_ff dq_f/ds = -K_fs."""
        m, a = self.model, self.a
        inner = np.array([i for i in range(m.n_dof) if i not in (self.driver, a)])
        q = self.continuation(q, inner)
        tol_T = self.tension_tolerance()
        for it in range(self.opts.max_iterations):
            T, dT = m.mean_tension_and_gradient(q)
            g = T - self.target
            if abs(g) <= tol_T:
                return q
            _, K = m.force_and_tangent(q)
            Kff = _submatrix(K, inner, inner, m.dense)
            Kfa = _submatrix(K, inner, np.array([a]), m.dense)
            Kfa = np.asarray(Kfa.todense() if not m.dense else Kfa).ravel()
            try:
                dqf = _solve(Kff, -Kfa, m.dense)
            except (np.linalg.LinAlgError, RuntimeError):
                dof = _null_dof(Kff, m.dense, inner, m.dof_labels)
                raise _Fail("singular tangent stiffness in the tension iteration", abs(g) / tol_T, dof) from None
            slope = float(dT[a] + dT[inner] @ dqf)
            if not abs(slope) > 1e-12 * float(m.elements.EA.max()):
                raise _Fail(f"the span tension does not change when the adjustable pulley moves "
                            f"(dT/ds = {slope:.3g} N/m)",
                            abs(g) / tol_T, m.dof_labels[a])
            step = -g / slope
            for _ in range(40):
                q_try = q.copy()
                q_try[a] += step
                q_try[inner] += step * dqf
                try:
                    q_new = self.newton(q_try, 1.0, inner)
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


def solve_static(cfg: DriveConfig, model: DriveModel) -> StaticResult:
    """Static equilibrium of the drive (raises SolverError naming step, residual and DOF).

    Tension mode "adjust": a bordered Newton on (equilibrium, T = target) from the linear axial
    predictor, which converges in one or two iterations for taut spans; if it fails (sagging spans,
    strong nonlinearity), an outer Newton on the slide offset around inner equilibrium solves with
    load stepping on the weight. Other modes: equilibrium with load stepping.
    """
    prob = _Problem(cfg, model)
    n = model.n_dof
    free = np.array([i for i in range(n) if i != prob.driver])
    try:
        if prob.adjust:
            q0 = _predictor(model, stretch_for_tension(prob.target, cfg.belt.EA), prob.a, prob.driver)
            try:
                q = prob.newton(q0, 1.0, free, bordered=True, max_iterations=8)
            except _Fail:
                prob.history.clear()
                q = prob.tension_loop(q0)
        else:
            q = prob.continuation(np.zeros(n), free)
    except _Fail as fail:
        lam = getattr(fail, "lam", 1.0)
        raise SolverError(f"{fail} (residual scaled so that 1 means converged)", analysis="static",
                          step=f"load factor {lam:.4g}", residual=fail.err, item=fail.dof) from None
    if prob.adjust:  # the bearing spring's preload follows from the adjustable pulley's slide equation
        f = model.internal_force(q)
        prob.preload[prob.a] = f[prob.a] - model.gravity_force[prob.a]
    hist = np.array(prob.history).reshape(-1, 2)
    return _result(cfg, model, q, prob.preload, hist[:, 0], hist[:, 1], len(hist), prob.driver)


def _result(cfg, model, q, preload, hist_r, hist_l, iterations, driver_dof) -> StaticResult:
    el = model.elements
    e = model.element_coordinates(q)
    fe = ancf.internal_forces(el, e)
    ge = ancf.gravity_forces(el, np.asarray(cfg.model.gravity, dtype=float))
    lay = model.layout
    n = lay.n
    hub = np.zeros((n, 2))
    for s in range(n):
        first, last = model.span_elements[s][0], model.span_elements[s][-1]
        hub[s] += ge[first, 0:2] - fe[first, 0:2]
        hub[(s + 1) % n] += ge[last, 4:6] - fe[last, 4:6]
    f = model.internal_force(q) - preload - model.gravity_force
    T_mean, _ = model.mean_tension_and_gradient(q)
    a = cfg.adjustable_index
    offset = lay.adjust_offset + (float(q[model.trans_dof[a][0]]) if a is not None else 0.0)
    return StaticResult(
        q=q, spring_preload=preload, span_tension=model.span_end_tensions(q, np.asarray(cfg.model.gravity, dtype=float)), mean_tension=T_mean,
        hub_load=hub, pulley_center=model.pulley_centers(q), pulley_rotation=q[model.rot_dof].copy(),
        driver_torque=float(f[driver_dof]), adjust_offset=offset,
        residual_history=np.array(hist_r), load_factor_history=np.array(hist_l), iterations=iterations,
        tension_mode=cfg.tension.mode if cfg.tension.target is not None else "geometry")
