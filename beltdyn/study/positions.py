"""Tensioner positions over the belt's life (`beltdyn positions`): for a drive whose tension is set by
a tensioner arm's spring (tension.mode = "spring"), the static equilibrium at the positions a drive is
specified by:

- FREE: no belt; the arm at its spring's free angle, clipped by its stops (arm_range).
- MIN / NOMINAL / MAX: the belt of length L0 - tol, L0, L0 + tol (tol: the length tolerance), without
  the static load case's accessory torques (the installed drive at rest).
- WORN: the belt lengthened by the wear fraction, L0 (1 + wear), without the torques.
- LOAD: the belt of length L0 under the static load case's torques ([[static.torque]]).

Each position is the plain static pipeline (`pipeline.analyse`) on the configuration with that
length and those torques, so NOMINAL is the plain static solution of the drive without torques and
LOAD the plain static solution of the drive as given. A position that fails (the arm beyond its
stops, a slack span, Newton not converging) is kept with its status and message and NaN values:
reported, not hidden.

Nomenclature: L0 belt length (m), phi arm angle (rad, counter-clockwise from +x), k arm spring
stiffness (N m/rad), phi_0 its free angle; the spring torque on the arm k (phi_0 - phi) (N m).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from beltdyn.config import DriveConfig
from beltdyn.errors import ConfigError, SolverError
from beltdyn.pipeline import analyse
from beltdyn.results.io import GroupData, Variable

POSITIONS = ("FREE", "MIN", "NOMINAL", "MAX", "WORN", "LOAD")
DEFAULT_LENGTH_TOLERANCE = 0.003  # relative to L0, when no --length-tolerance is given (not a standard's value)
DEFAULT_WEAR = 0.01  # belt lengthening by wear, fraction of L0 (an example value, not a standard's)


@dataclass(frozen=True, kw_only=True)
class PositionsResult:
    """The positions study. Shapes: m = len(positions) = 6, n pulleys (= n spans).

    positions: the position names (POSITIONS); belt_length (m,) m (NaN for FREE: no belt); status (m,)
    "ok" or what went wrong ("beyond stops", "slack span", "failed"); message (m,) the solver's message
    ("" if ok); arm_angle, spring_torque (m,) rad and N m of the tensioner arm; span_tension (m, n, 2)
    N at each span's start and end; hub_load (m, n, 2) N, force of the belt on each pulley;
    slip_margin (m, n) friction over the friction required (NaN: no friction given or no belt);
    arm_pulley: index of the arm's pulley; arm_range: its stops (lo, hi) rad or None;
    length_tolerance, wear: what was used (m, 1)."""

    positions: tuple[str, ...]
    belt_length: np.ndarray
    status: tuple[str, ...]
    message: tuple[str, ...]
    arm_angle: np.ndarray
    spring_torque: np.ndarray
    span_tension: np.ndarray
    hub_load: np.ndarray
    slip_margin: np.ndarray
    arm_pulley: int
    arm_range: tuple[float, float] | None
    length_tolerance: float
    wear: float

    @property
    def take_up_used(self) -> float:
        """The part of the arm's range (hi - lo) that the belt positions MIN..LOAD span (max - min of
        their arm angles) / (hi - lo); NaN without stops or with no solved position."""
        if self.arm_range is None:
            return float("nan")
        angles = self.arm_angle[1:][np.isfinite(self.arm_angle[1:])]
        if angles.size == 0:
            return float("nan")
        lo, hi = self.arm_range
        return float((angles.max() - angles.min()) / (hi - lo))

    @property
    def range_fraction(self) -> np.ndarray:
        """(m,) each position's arm angle within its stops: (phi - lo) / (hi - lo) (NaN without stops)."""
        if self.arm_range is None:
            return np.full(len(self.positions), np.nan)
        lo, hi = self.arm_range
        return (self.arm_angle - lo) / (hi - lo)


def spring_arm(cfg: DriveConfig) -> int:
    """The index of the tensioner arm pulley that sets the tension; ConfigError naming why not."""
    arms = [i for i, p in enumerate(cfg.pulleys) if p.support == "arm"]
    if not arms:
        raise ConfigError("positions needs a tensioner arm (a pulley with support = \"arm\"); this drive has none",
                          file=cfg.source, key="pulleys")
    if cfg.tension.mode != "spring":
        raise ConfigError(f"positions needs the arm's spring to set the tension (tension.mode = \"spring\"), got "
                          f"\"{cfg.tension.mode}\"", file=cfg.source, key="tension.mode")
    if len(arms) > 1:
        raise ConfigError(f"positions follows one tensioner arm; this drive has {len(arms)} (pulleys "
                          f"{', '.join(cfg.pulleys[i].name for i in arms)})", file=cfg.source, key="pulleys")
    return arms[0]


def position_config(cfg: DriveConfig, position: str, *, length_tolerance: float, wear: float) -> DriveConfig:
    """The configuration of one belt position (not FREE): its belt length, the torques only for LOAD."""
    L0 = cfg.belt.length
    length = {"MIN": L0 - length_tolerance, "NOMINAL": L0, "MAX": L0 + length_tolerance,
              "WORN": L0 * (1.0 + wear), "LOAD": L0}[position]
    static = cfg.static if position == "LOAD" else replace(cfg.static, torque=())
    return replace(cfg, belt=replace(cfg.belt, length=length), static=static)


def _status(exc: SolverError) -> str:
    text = str(exc)
    if "outside its stops" in text:
        return "beyond stops"
    if "slack" in text:
        return "slack span"
    return "failed"


def free_position(cfg: DriveConfig, arm: int) -> tuple[float, float]:
    """(phi, spring torque) with no belt: phi_0 clipped by the stops; the torque k (phi_0 - phi) the
    stop reacts (0 within the stops)."""
    p = cfg.pulleys[arm]
    phi0 = float(p.arm_free_angle)
    phi = phi0 if p.arm_range is None else min(max(phi0, p.arm_range[0]), p.arm_range[1])
    return phi, p.arm_stiffness * (phi0 - phi)


def tensioner_positions(cfg: DriveConfig, *, length_tolerance: float | None = None, wear: float | None = None
                        ) -> PositionsResult:
    """The static equilibrium at each position (see the module docstring). length_tolerance (m, default
    DEFAULT_LENGTH_TOLERANCE x L0); wear (fraction of L0, default DEFAULT_WEAR)."""
    arm = spring_arm(cfg)
    tol = DEFAULT_LENGTH_TOLERANCE * cfg.belt.length if length_tolerance is None else float(length_tolerance)
    wear = DEFAULT_WEAR if wear is None else float(wear)
    if not 0.0 <= tol < cfg.belt.length:
        raise ConfigError(f"the length tolerance must be in [0, belt.length), got {tol:g} m", file=cfg.source,
                          key="--length-tolerance")
    if not wear >= 0.0:
        raise ConfigError(f"the wear fraction must be >= 0, got {wear:g}", file=cfg.source, key="--wear")
    m, n = len(POSITIONS), len(cfg.pulleys)
    angle, torque = np.full(m, np.nan), np.full(m, np.nan)
    tension, hub = np.full((m, n, 2), np.nan), np.full((m, n, 2), np.nan)
    margin, length = np.full((m, n), np.nan), np.full(m, np.nan)
    status, message = ["ok"] * m, [""] * m
    angle[0], torque[0] = free_position(cfg, arm)
    if angle[0] != cfg.pulleys[arm].arm_free_angle:  # the free angle lies beyond the stops: say so
        status[0] = "at stop"
        message[0] = (f"the spring's free angle {cfg.pulleys[arm].arm_free_angle:g} rad lies beyond the stops "
                      f"arm_range = [{cfg.pulleys[arm].arm_range[0]:g}, {cfg.pulleys[arm].arm_range[1]:g}] rad: "
                      f"the arm rests on its stop, which reacts the spring torque")
    tension[0], hub[0] = 0.0, 0.0
    for k, name in enumerate(POSITIONS[1:], start=1):
        pos_cfg = position_config(cfg, name, length_tolerance=tol, wear=wear)
        length[k] = pos_cfg.belt.length
        try:
            st = analyse(pos_cfg, static=True).static
        except SolverError as exc:
            status[k], message[k] = _status(exc), str(exc)
            continue
        except ConfigError as exc:  # the belt of this length cannot be laid (the L0 fit): beyond stops or no fit
            status[k], message[k] = ("beyond stops" if exc.key.endswith("arm_range") else "no fit"), exc.detail
            continue
        angle[k], torque[k] = st.arm_angle[arm], st.arm_torque[arm]
        tension[k], hub[k] = st.span_tension, st.hub_load
        if st.slip_margin is not None:
            margin[k] = st.slip_margin
    p = cfg.pulleys[arm]
    return PositionsResult(positions=POSITIONS, belt_length=length, status=tuple(status), message=tuple(message),
                           arm_angle=angle, spring_torque=torque, span_tension=tension, hub_load=hub,
                           slip_margin=margin, arm_pulley=arm, arm_range=p.arm_range, length_tolerance=tol,
                           wear=wear)


def positions_group(cfg: DriveConfig, res: PositionsResult) -> GroupData:
    """/positions: every quantity against the `position` axis (FREE ... LOAD)."""
    names = [p.name for p in cfg.pulleys]
    spans = list(cfg.span_names)
    lo, hi = res.arm_range if res.arm_range is not None else (np.nan, np.nan)
    return GroupData(
        name="positions",
        coords={"position": list(res.positions), "pulley": names, "span": spans, "end": ["start", "end"],
                "component": ["x", "y"]},
        variables=(
            Variable(name="status", data=list(res.status), dims=("position",), units="1",
                     description='"ok", "beyond stops", "slack span", "no fit" or "failed" (the values are then NaN); '
                                 'FREE: "at stop" when the free angle lies beyond the stops'),
            Variable(name="message", data=list(res.message), dims=("position",), units="1",
                     description="the solver's message of a position that failed, or why FREE rests on a stop "
                                 "(empty if ok)"),
            Variable(name="belt_length", data=res.belt_length, dims=("position",), units="m",
                     description="undeformed belt length L0 of the position (NaN for FREE: no belt)"),
            Variable(name="arm_angle", data=res.arm_angle, dims=("position",), units="rad",
                     description="tensioner arm angle, counter-clockwise from +x"),
            Variable(name="range_fraction", data=res.range_fraction, dims=("position",), units="1",
                     description="arm angle within its stops: (angle - lo) / (hi - lo)"),
            Variable(name="spring_torque", data=res.spring_torque, dims=("position",), units="N m",
                     description="torque of the arm's spring on the arm, counter-clockwise positive (FREE: the "
                                 "stop's reaction if the free angle lies beyond the stops)"),
            Variable(name="span_tension", data=res.span_tension, dims=("position", "span", "end"), units="N",
                     description="axial force at the start and end of each span"),
            Variable(name="hub_load", data=res.hub_load, dims=("position", "pulley", "component"), units="N",
                     description="force of the belt on each pulley"),
            Variable(name="hub_load_magnitude", data=np.hypot(res.hub_load[..., 0], res.hub_load[..., 1]),
                     dims=("position", "pulley"), units="N"),
            Variable(name="slip_margin", data=res.slip_margin, dims=("position", "pulley"), units="1",
                     description="friction / friction required (inf: no torque to transmit; NaN: no friction "
                                 "given, no belt or failed)"),
        ),
        attrs={"arm_pulley": names[res.arm_pulley], "arm_range_lo_rad": float(lo), "arm_range_hi_rad": float(hi),
               "take_up_used": res.take_up_used, "length_tolerance_m": res.length_tolerance, "wear": res.wear},
    )
