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
    span_tension: np.ndarray  # (n, 2) true axial force at the start/end of each span, N
    mean_tension: float  # N, length-weighted mean over all spans
    hub_load: np.ndarray  # (n, 2) force of the belt on each pulley, N
    pulley_center: np.ndarray  # (n, 2) m
    pulley_rotation: np.ndarray  # (n,) rad
    driver_torque: float  # N m, torque the driver's support applies to hold it
    adjust_offset: float  # m, total travel of the adjustable pulley from its given centre
    residual_history: np.ndarray  # (n_iter,) scaled residual norm after each Newton iteration
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


def solve_static(cfg: DriveConfig, model: DriveModel) -> StaticResult:
    """Static equilibrium of the drive (raises SolverError naming step, residual and DOF)."""
    n = model.n_dof
    opts = cfg.static
    target = cfg.tension.target
    adjust = target is not None and cfg.tension.mode == "adjust"
    driver_dof = int(model.rot_dof[cfg.driver_index])
    a_dof = model.trans_dof[cfg.adjustable_index][0] if adjust else -1
    free = np.array([i for i in range(n) if i != driver_dof])
    pos = {d: i for i, d in enumerate(free)}
    q = np.zeros(n)
    if adjust:
        q = _predictor(model, stretch_for_tension(target, cfg.belt.EA), a_dof, driver_dof)
    f_g = model.gravity_force
    preload = np.zeros(n)
    hist_r: list[float] = []
    hist_l: list[float] = []

    def residual(q: np.ndarray, lam: float, with_tangent: bool):
        if with_tangent:
            f, K = model.force_and_tangent(q)
        else:
            f, K = model.internal_force(q), None
        R = f - preload - lam * f_g
        scale = max(abs(target) if target else 0.0, float(np.abs(lam * f_g).max(initial=0.0)),
                    1e-9 * float(model.elements.EA[0]))
        if adjust:
            T, dT = model.mean_tension_and_gradient(q)
            R[a_dof] = (T - target)
            if K is not None:
                if model.dense:
                    K = K.copy()
                    K[a_dof, :] = dT
                else:
                    from scipy.sparse import csr_matrix, diags

                    keep = np.ones(n)
                    keep[a_dof] = 0.0
                    row = csr_matrix((dT, (np.full(n, a_dof), np.arange(n))), shape=(n, n))
                    K = (diags(keep) @ K + row).tocsr()
        Rf = R[free]
        if K is not None:
            K = K[np.ix_(free, free)] if model.dense else K[free][:, free]
        return Rf, K, float(np.abs(Rf).max()) / scale

    steps = opts.load_steps
    lam_done = 0.0
    dlam = 1.0 / steps
    it_total = 0
    has_load = bool(np.any(f_g != 0.0))
    if not has_load:
        lam_done, dlam = 0.0, 1.0
    while lam_done < 1.0 - 1e-14:
        lam = min(1.0, lam_done + dlam)
        q_start = q.copy()
        ok, q, err_msg = _newton(residual, q, lam, opts, model, free, hist_r, hist_l)
        it_total = len(hist_r)
        if ok:
            lam_done = lam
            dlam = min(dlam * 2.0, 1.0 - lam_done) if lam_done < 1.0 else dlam
            continue
        q = q_start
        if not has_load or dlam < 1.0 / 64:
            raise SolverError(err_msg[0], analysis="static", step=f"load factor {lam:.4g}",
                              residual=err_msg[1], item=err_msg[2])
        dlam *= 0.5
    # Spring preload of the adjustable pulley: its slide equation holds with p.
    f = model.internal_force(q)
    if adjust:
        preload[a_dof] = f[a_dof] - f_g[a_dof]
    return _result(cfg, model, q, preload, hist_r, hist_l, it_total, driver_dof)


def _newton(residual, q, lam, opts, model, free, hist_r, hist_l):
    pos_labels = model.dof_labels
    R, K, err = residual(q, lam, True)
    for it in range(opts.max_iterations):
        if err <= opts.tolerance:
            return True, q, None
        try:
            dq = _solve(K, -R, model.dense)
        except (np.linalg.LinAlgError, RuntimeError):
            dof = _null_dof(K, model.dense, free, pos_labels)
            return False, q, (f"singular tangent stiffness in Newton iteration {it + 1} "
                              f"(no stiffness against a motion of '{dof}')", err, dof)
        full = np.zeros(model.n_dof)
        full[free] = dq
        alpha = 1.0
        for _ in range(12):
            q_try = q + alpha * full
            R_try, K_try, err_try = residual(q_try, lam, True)
            if np.isfinite(err_try) and (err_try < err * (1.0 - 1e-4 * alpha) or err_try <= opts.tolerance):
                break
            alpha *= 0.5
        else:
            worst = pos_labels[int(free[int(np.argmax(np.abs(R)))])]
            return False, q, (f"line search failed in Newton iteration {it + 1}", err, worst)
        q, R, K, err = q_try, R_try, K_try, err_try
        hist_r.append(err)
        hist_l.append(lam)
    if err <= opts.tolerance:
        return True, q, None
    worst = pos_labels[int(free[int(np.argmax(np.abs(R)))])]
    return False, q, (f"Newton did not converge in {opts.max_iterations} iterations", err, worst)


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
        q=q, spring_preload=preload, span_tension=model.span_end_tensions(q), mean_tension=T_mean,
        hub_load=hub, pulley_center=model.pulley_centers(q), pulley_rotation=q[model.rot_dof].copy(),
        driver_torque=float(f[driver_dof]), adjust_offset=offset,
        residual_history=np.array(hist_r), load_factor_history=np.array(hist_l), iterations=iterations,
        tension_mode=cfg.tension.mode if cfg.tension.target is not None else "geometry")
