"""The belt on its pulleys: the creep law of one wrap (Grashof, Firbank, Johnson).

A belt running over a pulley of wrap angle beta (rad) and radius R (m) enters the wrap with the
tension of the span that arrives in the direction of travel (T_e, the entry) and leaves it with the
tension of the span that departs (T_x, the exit). With creep wraps the wrap carries

- an adhesion arc at its entry, where the belt sticks to the rim and keeps the entry tension T_e
  (and with it the entry stretch lambda_e: the rim moves at the belt's speed there), and
- one slip arc at its exit, over which the tension goes exponentially (capstan) to the exit tension,

      T(phi) - c = (T_e - c) exp(-/+ mu phi),   0 <= phi <= phi_s,
      phi_s = |ln((T_e - c) / (T_x - c))| / mu,

  mu the belt-pulley friction coefficient (the user's effective value), c = rho v^2 lambda the
  centrifugal part of the tension (rho the mass per unit reference length, v the reference
  (mass-flow) speed, lambda the stretch: the true-force form of rho v_true^2 / lambda; 0 at rest;
  the statics take one c for the drive, the slip margin's, at the mean span tension, so that the
  slip arc and the margin agree exactly: `wrap_state(centrifugal=...)`). The slip arc is absent where the two tensions are equal (idlers, backside pulleys without
  torque: `ROUND_OFF` of `model.slip`), and a pulley without a friction value never slips (phi_s = 0,
  the limit mu -> inf: its stretch changes at the exit point, and its creep loss, independent of mu, stays).
  Where phi_s > beta the wrap cannot hold the tension ratio: gross slip (the slip margin < 1;
  phi_s / beta = 1 / margin exactly, both from the same capstan law).

Outputs of a wrap:
- stress-free (reference) length: R alpha_a / lambda(T_e) + R int_0^phi_s dphi / lambda(T(phi)),
  alpha_a = beta - phi_s the adhesion arc (the slip arc integrated over the varying stretch of the
  bar law in use, Gauss-Legendre on `QUADRATURE_POINTS` points: the integrand is smooth and the
  quadrature exact to round-off for the arcs of a belt drive);
- rim speed ratio: the rim moves with the belt in the adhesion arc, at v lambda(T_e), so the rim
  speed of pulley j over the driver's is lambda(T_e,j) / lambda(T_e,driver) (to first order
  (1 + T_e,j / EA) / (1 + T_e,driver / EA)); 1 with rigid wraps;
- creep power loss (W): in the slip arc the belt moves against the rim at v (lambda(T) - lambda(T_e))
  while the friction force per unit angle is |dT/dphi|, so the loss is
      P = v |int_{T_x}^{T_e} (lambda(T_e) - lambda(T)) dT|
  (v (T_e - T_x)^2 / (2 EA) for the linear law; 0 at rest). The losses of all wraps add up to the
  power the belt delivers to the pulleys, sum_j (T_e,j - T_x,j) v lambda(T_e,j) (the strain-energy
  flux terms cancel around the loop), the energy balance of the steady running drive.

Nomenclature: T tension (true axial force, N), c centrifugal tension (N), lambda stretch (1), EA
axial stiffness (N), mu friction coefficient (1), beta wrap angle (rad), phi angle into the slip arc
(rad), R pulley radius (m), v reference belt speed (m/s). Arrays are (n,), one entry per pulley.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from beltdyn.config import WRAP_MODELS
from beltdyn.model.barlaw import bar_law, stretch_for_tension
from beltdyn.model.slip import ROUND_OFF, pulley_tensions

QUADRATURE_POINTS = 24  # Gauss-Legendre points of the slip-arc integrals

_XI, _W = np.polynomial.legendre.leggauss(QUADRATURE_POINTS)  # on [-1, 1]
_XI = 0.5 * (_XI + 1.0)  # on [0, 1]
_W = 0.5 * _W


@dataclass(frozen=True, kw_only=True)
class WrapState:
    """The wraps of a drive at one equilibrium (module docstring). Shapes: (n,) per pulley."""

    entry_tension: np.ndarray  # N, tension of the span entering each wrap (direction of travel)
    exit_tension: np.ndarray  # N, tension of the span leaving it
    slip_arc: np.ndarray  # rad, the capstan slip arc phi_s (may exceed the wrap: see gross_slip)
    adhesion_arc: np.ndarray  # rad, max(wrap - slip_arc, 0)
    gross_slip: np.ndarray  # bool, slip_arc > wrap: the wrap cannot hold its tension ratio
    stress_free_length: np.ndarray  # m, the wrap's reference length (the slip arc clipped to the wrap)
    rim_speed_ratio: np.ndarray  # 1, rim speed over the driver's
    creep_power_loss: np.ndarray  # W, at the belt speed (0 at rest)


def entry_exit(t_in: np.ndarray, t_out: np.ndarray, belt_speed: float) -> tuple[np.ndarray, np.ndarray]:
    """(T_e, T_x) (n,) of each wrap from the tensions of its arriving span (span j-1's end, t_in) and
    departing span (span j's start, t_out): the belt travels along the span order for belt_speed >= 0
    (at rest too), against it otherwise."""
    return (t_in, t_out) if belt_speed >= 0.0 else (t_out, t_in)


def slip_arc(t_entry: np.ndarray, t_exit: np.ndarray, friction: np.ndarray, centrifugal=0.0) -> np.ndarray:
    """phi_s (n,) = |ln((T_e - c) / (T_x - c))| / mu: 0 where the tensions are equal to round-off or no
    friction is given (NaN: never slips), inf where a span is slack (T - c <= 0)."""
    te, tx = np.asarray(t_entry, dtype=float), np.asarray(t_exit, dtype=float)
    mu = np.asarray(friction, dtype=float)
    c = np.asarray(centrifugal, dtype=float)
    equal = np.abs(te - tx) <= ROUND_OFF * np.maximum(np.abs(te), np.abs(tx))
    a, b = te - c, tx - c
    taut = (a > 0.0) & (b > 0.0)
    has_mu = mu == mu
    ratio = np.where(taut & ~equal, a / np.where(taut, b, 1.0), 1.0)
    arc = np.abs(np.log(ratio)) / np.where(has_mu & (mu > 0.0), mu, 1.0)
    arc = np.where(taut, arc, np.inf)
    arc = np.where(has_mu & (mu > 0.0), arc, np.where(has_mu, np.inf, 0.0))  # mu = 0: slips at any ratio
    return np.where(equal | ~has_mu, 0.0, arc)


def _slip_tensions(t_entry, t_exit, centrifugal, arc) -> np.ndarray:
    """(n, QUADRATURE_POINTS) tensions at the quadrature points of each slip arc (exponential in phi
    from T_e to T_x over the arc: T - c = (T_e - c) ((T_x - c)/(T_e - c))^(phi / arc))."""
    a = (t_entry - centrifugal)[:, None]
    b = (t_exit - centrifugal)[:, None]
    ok = (a > 0.0) & (b > 0.0)
    ratio = np.where(ok, b / np.where(ok, a, 1.0), 1.0)
    linear = a + (b - a) * _XI[None, :]  # (a slack wrap: no capstan profile; linear in phi)
    return np.asarray(centrifugal)[..., None] * np.ones_like(a) + np.where(ok, a * ratio ** _XI[None, :], linear)


def stress_free_length(radius, wrap, t_entry, t_exit, arc, EA: float, centrifugal=0.0,
                       stretch: Callable = stretch_for_tension) -> np.ndarray:
    """The wraps' reference lengths (n,): R (beta - phi) / lambda(T_e) + R int_0^phi dphi / lambda(T),
    phi = min(arc, beta) (module docstring); `stretch(T, EA)` the bar law's inverse."""
    return _lengths_and_entry_stretch(radius, wrap, t_entry, t_exit, arc, EA, centrifugal, stretch)[0]


def _lengths_and_entry_stretch(radius, wrap, t_entry, t_exit, arc, EA: float, centrifugal,
                               stretch: Callable) -> tuple[np.ndarray, np.ndarray]:
    """(`stress_free_length` (n,), the entry stretches lambda(T_e) (n,)): one call of the bar law's inverse."""
    R, beta = np.asarray(radius, dtype=float), np.asarray(wrap, dtype=float)
    te, tx = np.asarray(t_entry, dtype=float), np.asarray(t_exit, dtype=float)
    c = np.broadcast_to(np.asarray(centrifugal, dtype=float), te.shape)
    phi = np.minimum(np.asarray(arc, dtype=float), beta)
    at = np.empty((te.shape[0], QUADRATURE_POINTS + 1))  # the slip arc's tensions, then the entry's
    at[:, :-1] = _slip_tensions(te, tx, c, phi)
    at[:, -1] = te
    lam = stretch(at, EA)
    lam_e = lam[:, -1]
    return R * (beta - phi) / lam_e + R * phi * ((_W[None, :] / lam[:, :-1]).sum(axis=1)), lam_e


def rim_speed_ratio(t_entry, driver: int, EA: float, stretch: Callable = stretch_for_tension, *,
                    entry_stretch: np.ndarray | None = None) -> np.ndarray:
    """(n,) lambda(T_e,j) / lambda(T_e,driver): each pulley's rim speed over the driver's (entry_stretch:
    lambda(T_e) (n,), if at hand)."""
    lam = stretch(np.asarray(t_entry, dtype=float), EA) if entry_stretch is None else entry_stretch
    return lam / lam[driver]


def creep_power_loss(t_entry, t_exit, belt_speed: float, EA: float,
                     stretch: Callable = stretch_for_tension) -> np.ndarray:
    """(n,) P = |v| |int_{T_x}^{T_e} (lambda(T_e) - lambda(T)) dT| (W), v the reference belt speed; 0
    where the two tensions are equal to round-off (`ROUND_OFF`: no slip arc)."""
    te, tx = np.asarray(t_entry, dtype=float), np.asarray(t_exit, dtype=float)
    if not belt_speed:
        return np.zeros(te.shape)
    T = tx[:, None] + (te - tx)[:, None] * _XI[None, :]
    integral = (te - tx) * ((_W[None, :] * (stretch(te, EA)[:, None] - stretch(T, EA))).sum(axis=1))
    equal = np.abs(te - tx) <= ROUND_OFF * np.maximum(np.abs(te), np.abs(tx))  # no slip arc: no loss
    return np.where(equal, 0.0, abs(float(belt_speed)) * np.abs(integral))


def wrap_state(*, t_in: np.ndarray, t_out: np.ndarray, radius: np.ndarray, wrap: np.ndarray, friction,
               EA: float, mass_per_length: float, belt_speed: float, driver: int, model: str = "creep",
               stretch: Callable = stretch_for_tension, centrifugal=None) -> WrapState:
    """The wraps of a drive (`WrapState`) from the span tensions at each pulley (`slip.pulley_tensions`),
    the radii and wrap angles (n,), the friction coefficients (n,; NaN: none given, or None), the
    belt's EA (N), mass per unit reference length (kg/m) and reference speed (m/s), the driver's index.
    A pulley without friction has no slip arc (it never slips: the limit mu -> inf) but its creep loss, which
    does not depend on mu (the losses of all wraps add up to the power the belt delivers).
    model "rigid": no slip arc, the wraps inextensible (reference length R beta), rim speeds equal.
    centrifugal: c (N) of the slip arcs, one for the drive (the slip margin's, `slip.drive_centrifugal_tension`,
    so that slip arc / wrap = 1 / slip margin exactly); None: rho v^2 lambda(T_e) of each wrap's entry."""
    te, tx = entry_exit(np.asarray(t_in, dtype=float), np.asarray(t_out, dtype=float), belt_speed)
    n = te.shape[0]
    R, beta = np.asarray(radius, dtype=float), np.asarray(wrap, dtype=float)
    if model == "rigid":
        z = np.zeros(n)
        return WrapState(entry_tension=te, exit_tension=tx, slip_arc=z, adhesion_arc=beta.copy(),
                         gross_slip=np.zeros(n, dtype=bool), stress_free_length=R * beta, rim_speed_ratio=np.ones(n),
                         creep_power_loss=z.copy())
    if model != "creep":
        raise ValueError(f"unknown wrap model {model!r}: one of {', '.join(WRAP_MODELS)}")
    mu = np.full(n, np.nan) if friction is None else np.asarray(friction, dtype=float)
    c = (centrifugal_tension(te, mass_per_length, belt_speed, EA, stretch) if centrifugal is None
         else np.full(n, float(centrifugal)))
    arc = slip_arc(te, tx, mu, c)
    length, lam_e = _lengths_and_entry_stretch(R, beta, te, tx, arc, EA, c, stretch)
    return WrapState(entry_tension=te, exit_tension=tx, slip_arc=arc, adhesion_arc=np.maximum(beta - arc, 0.0),
                     gross_slip=arc > beta, stress_free_length=length,
                     rim_speed_ratio=rim_speed_ratio(te, driver, EA, stretch, entry_stretch=lam_e),
                     creep_power_loss=creep_power_loss(te, tx, belt_speed, EA, stretch))


def centrifugal_tension(t_entry, mass_per_length: float, belt_speed: float, EA: float,
                        stretch: Callable = stretch_for_tension) -> np.ndarray:
    """c (n,) = rho v^2 lambda(T_e) (N) of each wrap, rho per unit reference length, v the reference
    speed, the stretch at the wrap's entry; 0 at rest."""
    te = np.asarray(t_entry, dtype=float)
    if not belt_speed:
        return np.zeros(te.shape)
    return float(mass_per_length) * float(belt_speed) ** 2 * stretch(te, EA)


@dataclass(frozen=True, kw_only=True)
class WrapModel:
    """How the belt sits on the pulleys of one drive: the wrap model (belt.wraps, one of `WRAP_MODELS`),
    the bar law (belt.axial_law, `barlaw.LAWS`) and the belt facts the wraps need. Shapes: (n,) per pulley."""

    kind: str = "creep"
    axial_law: str = "green-lagrange"
    EA: float  # N
    mass_per_length: float  # kg/m of reference length
    friction: np.ndarray  # (n,) belt-pulley friction coefficients, NaN where none is given (never slips)

    def __post_init__(self) -> None:
        if self.kind not in WRAP_MODELS:
            raise ValueError(f"unknown wrap model {self.kind!r}: one of {', '.join(WRAP_MODELS)}")
        self.friction.flags.writeable = False  # (the array is the model's: frozen with it)

    @property
    def stretch(self) -> Callable:
        """lambda(T, EA) of the bar law in use."""
        return bar_law(self.axial_law).stretch_for_tension


def wrap_model_state(wm: WrapModel, *, span_tension: np.ndarray, radius: np.ndarray, wrap: np.ndarray,
                     belt_speed: float, driver: int, centrifugal: float) -> WrapState:
    """`wrap_state` of a drive's `WrapModel` at span tensions (n_span, 2) (start, end of each span), the
    drive's centrifugal tension c (N)."""
    t_in, t_out = pulley_tensions(np.asarray(span_tension, dtype=float))
    return wrap_state(t_in=t_in, t_out=t_out, radius=radius, wrap=wrap, friction=wm.friction, EA=wm.EA,
                      mass_per_length=wm.mass_per_length, belt_speed=belt_speed, driver=driver, model=wm.kind,
                      stretch=wm.stretch, centrifugal=centrifugal)


def wrap_lengths(wm: WrapModel, *, span_tension: np.ndarray, radius: np.ndarray, wrap: np.ndarray,
                 belt_speed: float, centrifugal: float = 0.0) -> np.ndarray:
    """(n,) the wraps' stress-free lengths at span tensions (n_span, 2), or (n_span,) one tension per span,
    the drive's centrifugal tension c (N): with creep wraps `stress_free_length` (the adhesion arc at the
    entry stretch, the slip arc integrated; what `wrap_model_state` reports), with rigid wraps the arc
    lengths R beta (the belt-length budget of `analysis.static.tension`)."""
    R, beta = np.asarray(radius, dtype=float), np.asarray(wrap, dtype=float)
    if wm.kind == "rigid":
        return R * beta
    T = np.asarray(span_tension, dtype=float)
    if T.ndim == 1:
        T = np.stack([T, T], axis=1)
    te, tx = entry_exit(*pulley_tensions(T), belt_speed)
    c = np.full(te.shape, float(centrifugal))
    arc = slip_arc(te, tx, wm.friction, c)
    return stress_free_length(R, beta, te, tx, arc, wm.EA, c, wm.stretch)


def slip_part(wm: WrapModel, *, span_tension: np.ndarray, radius: np.ndarray, wrap: np.ndarray,
              centrifugal: float = 0.0) -> float:
    """delta (m) = sum_j R_j (int_0^phi_j dphi / lambda(T(phi)) - phi_j / lambda(T_e,j)), phi_j the slip arc
    clipped to the wrap: what the slip arcs add to the wraps' stress-free length beyond the adhesion
    stretch R beta / lambda(T_e), at rest, the belt running along the span order, one tension per span
    (n,) (pulley j entered by span j - 1). The same sum as `wrap_lengths` less the adhesion part, computed
    on the pulleys with a slip arc alone (the statics' predictor evaluates it often); the drive's
    centrifugal tension c (N; 0 at rest) in the slip arcs as in `wrap_state`; 0 where a span is slack
    (T - c <= 0: no capstan law holds; the predictor's trial layouts only)."""
    T = np.asarray(span_tension, dtype=float)
    te = np.concatenate((T[-1:], T[:-1]))  # (np.roll(T, 1) without its cost)
    c = float(centrifugal)
    if wm.kind == "rigid" or not (T - c > 0.0).all():
        return 0.0  # (a slack span: no capstan profile; the statics' predictor meets it only on trial layouts)
    # `slip_arc`, all tensions above c, in fewer operations (NaN friction: no arc; 0: the whole wrap)
    with np.errstate(divide="ignore"):
        phi = np.abs(np.log((te - c) / (T - c))) / wm.friction
    k = (phi > 0.0) & (np.abs(te - T) > ROUND_OFF * np.maximum(te, T))
    if not k.any():
        return 0.0
    a, b, phi = te[k], T[k], np.minimum(phi[k], wrap[k])
    m = len(a)
    at = np.empty((m, QUADRATURE_POINTS + 1))  # T(phi) at the quadrature points, then the entry tension
    np.power(((b - c) / (a - c))[:, None], _XI[None, :], out=at[:, :-1])
    at[:, :-1] *= (a - c)[:, None]
    at[:, :-1] += c
    at[:, -1] = a
    lam = wm.stretch(at, wm.EA)  # (one call of the bar law's inverse for both)
    inner = (_W[None, :] / lam[:, :-1]).sum(axis=1) - 1.0 / lam[:, -1]
    return float((radius[k] * phi * inner).sum())
