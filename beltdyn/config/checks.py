"""The checks that involve several keys, after the generic parse (one adjustable pulley, the spring
tension mode, the spans, the static torques, the response, the transient's cross-checks); each
raises `ConfigError` with the file and the key path."""

from __future__ import annotations

import difflib
import math
from dataclasses import replace
from typing import Any

from beltdyn.config.kinds import _Checker, _num, _show
from beltdyn.config.schema import (Pulley, ResponseOptions, span_name_key, span_names, SpanSetting, StaticOptions,
                                   Tension, TransientOptions)
from beltdyn.config.tables import _read_table


def _check_spring_tension(chk: _Checker, tension: Tension, pulleys: tuple[Pulley, ...]) -> None:
    """mode "spring": an arm pulley with a spring and its free angle sets the tension (no target)."""
    if tension.target is not None:
        raise chk.fail("tension.target", "with mode = \"spring\" the arm's spring sets the tension (an output): "
                                         "remove tension.target, or use mode = \"adjust\"")
    arms = [i for i, p in enumerate(pulleys) if p.support == "arm"]
    if not arms:
        raise chk.fail("tension.mode", "mode \"spring\" needs a pulley with support = \"arm\"")
    for i in arms:
        p = pulleys[i]
        if p.arm_free_angle is None:
            raise chk.fail(f"pulleys[{i}].arm_free_angle", "missing key: tension mode \"spring\" needs the angle "
                                                          "at which the arm's spring torque is zero (rad)")
        if not p.arm_stiffness > 0:
            raise chk.fail(f"pulleys[{i}].arm_stiffness", "tension mode \"spring\" needs arm_stiffness > 0")


def _check_length_tension(chk: _Checker, tension: Tension, pulleys: tuple[Pulley, ...]) -> None:
    """mode "length": the belt's undeformed length on the centres as given sets the tension (no target, no
    adjustable pulley)."""
    if tension.target is not None:
        raise chk.fail("tension.target", "with mode = \"length\" the belt's length on the given centres sets the "
                                         "tension (an output): remove tension.target, or use mode = \"prestrain\"")
    for i, p in enumerate(pulleys):
        if p.adjustable:
            raise chk.fail(f"pulleys[{i}].adjustable", "tension mode \"length\" keeps every centre as given: "
                                                       "no pulley is adjustable")


def _check_spans(chk: _Checker, spans: tuple[tuple[str, SpanSetting], ...], pulleys: tuple[Pulley, ...]) -> None:
    """Every [spans] entry names a span of the drive (the closest name suggested)."""
    valid = span_names(pulleys)
    for name, _ in spans:
        if valid.count(name) == 1:
            continue
        key = f"spans.{span_name_key(name)}"
        if valid.count(name) > 1:
            raise chk.fail(key, f"span name '{name}' is ambiguous (pulley names with '-'); rename the pulleys")
        close = difflib.get_close_matches(name, valid, n=1, cutoff=0.4)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise chk.fail(key, f"no span named '{name}'; {hint}the spans are {', '.join(valid)} (from each pulley "
                            f"to the next in belt order)")


def _check_static_torques(chk: _Checker, opts: StaticOptions, pulleys: tuple[Pulley, ...]) -> None:
    names = [p.name for p in pulleys]
    driver = next((i for i, p in enumerate(pulleys) if p.driver), 0)
    for i, tq in enumerate(opts.torque):
        j = _pulley_index(chk, f"static.torque[{i}].pulley", tq.pulley, names)
        if j == driver:
            raise chk.fail(f"static.torque[{i}].pulley", f"'{tq.pulley}' is the driver: its rotation is held and "
                                                         f"reacts the torques; put the torque on an accessory")


def _check_pulleys(chk: _Checker, raw: list[dict[str, Any]], pulleys: tuple[Pulley, ...]) -> tuple[Pulley, ...]:
    out = []
    for i, (p, praw) in enumerate(zip(pulleys, raw)):
        key = f"pulleys[{i}]"
        dx, dy = p.slide_direction
        norm = math.hypot(dx, dy)
        if norm == 0:
            raise chk.fail(f"{key}.slide_direction", "must not be the zero vector")
        if abs(norm - 1.0) > 4 * 2.0**-52:  # a unit vector (to rounding) is kept as given, so that
            p = replace(p, slide_direction=(dx / norm, dy / norm))  # the resolved TOML round-trips
        if p.support == "fixed" and any(p.bearing_stiffness):
            raise chk.fail(f"{key}.bearing_stiffness", "a fixed-centre pulley has no bearing spring; "
                           "use support = \"slide\" or \"bearing\"")
        if p.support == "slide" and isinstance(praw.get("bearing_stiffness"), list):
            raise chk.fail(f"{key}.bearing_stiffness", "a slide has one stiffness (N/m along the slide)")
        if p.adjustable and p.support not in ("slide", "arm"):
            raise chk.fail(f"{key}.adjustable", "the adjustable pulley needs support = \"slide\" or \"arm\"")
        arm_keys = [k for k in ("arm_pivot", "arm_inertia", "arm_stiffness", "arm_free_angle", "arm_damping",
                                "arm_friction", "arm_friction_unloading", "arm_range") if k in praw]
        if p.support != "arm" and arm_keys:
            raise chk.fail(f"{key}.{arm_keys[0]}", "only a pulley with support = \"arm\" has arm settings")
        if p.support == "arm":
            if p.arm_pivot is None:
                raise chk.fail(f"{key}.arm_pivot", "missing key: an arm pulley needs arm_pivot = [x, y] (m)")
            if any(p.bearing_stiffness):
                raise chk.fail(f"{key}.bearing_stiffness", "an arm pulley has no bearing spring: its arm has "
                                                          "arm_stiffness (N m/rad)")
            if p.arm_friction_unloading is not None and p.arm_free_angle is None:
                raise chk.fail(f"{key}.arm_friction_unloading", "needs arm_free_angle: loading and unloading are "
                                                               "the arm turning away from and toward it")
            if p.arm_length <= p.radius:
                raise chk.fail(f"{key}.arm_pivot", f"the pivot lies inside the pulley (arm length "
                                                  f"{p.arm_length:.6g} m <= radius {p.radius:g} m)")
        if p.slide_range is not None and p.support != "slide":
            raise chk.fail(f"{key}.slide_range", "only a slide pulley has a slide range")
        out.append(p)
    names = [p.name for p in out]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise chk.fail(f"pulleys[{i}].name", f"duplicate pulley name '{n}'")
    adjustable = [i for i, p in enumerate(out) if p.adjustable]
    if len(adjustable) > 1:
        raise chk.fail(f"pulleys[{adjustable[1]}].adjustable",
                       f"only one pulley may be adjustable (pulleys[{adjustable[0]}] already is)")
    drivers = [i for i, p in enumerate(out) if p.driver]
    if len(drivers) > 1:
        raise chk.fail(f"pulleys[{drivers[1]}].driver", "only one pulley may be the driver")
    driver = drivers[0] if drivers else 0
    if out[driver].decoupler is not None:
        raise chk.fail(f"pulleys[{driver}].decoupler", "the driver's rotation is held (it reacts the torques): a "
                                                       "decoupler belongs on an accessory (an alternator's pulley)")
    return tuple(out)


def _check_response(chk: _Checker, r: ResponseOptions, pulleys: tuple[Pulley, ...]) -> None:
    names = [p.name for p in pulleys]
    driver = next((i for i, p in enumerate(pulleys) if p.driver), 0)
    if not r.speed[0] > 0:
        raise chk.fail("response.speed", f"the driver's speeds must be > 0 (an excitation at order x speed), "
                                         f"got [{_num(r.speed[0])}, {_num(r.speed[1])}]")
    prescribed = {driver} | {names.index(e.pulley) for e in r.excitation if e.kind == "speed" and e.pulley in names}
    for i, e in enumerate(r.excitation):
        key = f"response.excitation[{i}]"
        j = _pulley_index(chk, f"{key}.pulley", e.pulley, names)
        if e.kind == "torque" and j in prescribed:
            raise chk.fail(f"{key}.pulley", f"pulley '{e.pulley}' has a prescribed rotation (the driver, or a speed "
                                            f"excitation): a torque on it goes into that prescription")
        if e.order and e.order not in r.orders:
            raise chk.fail(f"{key}.order", f"order {_num(e.order)} is not one of response.orders "
                                           f"{list(r.orders)}: it would never act")


def _pulley_index(chk: _Checker, key: str, name: str, names: list[str]) -> int:
    if name not in names:
        raise chk.fail(key, f"no pulley named {_show(name)}; pulleys are {', '.join(names)}")
    return names.index(name)


def _check_transient(chk: _Checker, t: TransientOptions, pulleys: tuple[Pulley, ...], file: str) -> TransientOptions:
    names = [p.name for p in pulleys]
    for i, r in enumerate(t.rotation):
        key = f"transient.rotation[{i}]"
        _pulley_index(chk, f"{key}.pulley", r.pulley, names)
        if r.amplitude and r.speed_amplitude:
            raise chk.fail(f"{key}.speed_amplitude", "give either amplitude (angle) or speed_amplitude, not both")
        if r.order > 0:
            if r.frequency:
                raise chk.fail(f"{key}.frequency", "give either order (follows the speed) or frequency, not both")
            if r.speed == 0.0:
                raise chk.fail(f"{key}.order", "an engine-order fluctuation needs a mean speed (speed != 0)")
        elif (r.amplitude or r.speed_amplitude) and not r.frequency > 0:
            raise chk.fail(f"{key}.frequency", "a fluctuation needs frequency > 0 (or an engine order)")
        if r.start_speed != 0.0 and not r.ramp_time > 0.0:
            raise chk.fail(f"{key}.start_speed", "a start speed is where a ramp starts: give ramp_time > 0 (without "
                                                 "a ramp the rotation runs at `speed` from the start)")
    if len(t.rotation) > 1:
        raise chk.fail("transient.rotation[1]", "only one pulley rotation can be prescribed")
    loads = []
    count = {"torque": 0, "hub_force": 0}
    for load in t.loads:
        key = f"transient.{load.kind}[{count[load.kind]}]"
        count[load.kind] += 1
        j = _pulley_index(chk, f"{key}.pulley", load.pulley, names)
        if load.kind == "hub_force" and pulleys[j].support == "fixed":
            raise chk.fail(f"{key}.pulley", f"pulley '{load.pulley}' has a fixed centre: a hub force "
                                            f"on it goes straight into the ground (give it a slide or bearing)")
        s0 = load.signals[0]
        if any(s.amplitude for s in load.signals) and not s0.frequency > 0:
            raise chk.fail(f"{key}.frequency", "a harmonic load needs frequency > 0")
        if s0.table:
            sha, cols = _read_table(chk, f"{key}.table", s0.table, file, len(load.signals), s0.table_sha256)
            load = replace(load, signals=tuple(replace(s, table_sha256=sha, table_time=cols[0], table_value=cols[1 + c])
                                               for c, s in enumerate(load.signals)))
        elif s0.table_sha256:
            raise chk.fail(f"{key}.table_sha256", "given without a table")
        loads.append(load)
    t = replace(t, loads=tuple(loads))
    if t.spectrum.enabled and t.spectrum.start >= t.duration:
        raise chk.fail("transient.spectrum.start", f"must be < transient.duration ({t.duration:g} s), got "
                                                   f"{t.spectrum.start:g}; or set transient.spectrum.enabled = false")
    if t.orders.orders:
        o = t.orders
        if o.reference is not None:
            _pulley_index(chk, "transient.orders.reference", o.reference, names)
        elif not t.rotation:
            raise chk.fail("transient.orders.reference", "missing key: no [[transient.rotation]] to take the "
                                                         "reference pulley from")
        if not t.record.pulley_angles:
            raise chk.fail("transient.record.pulley_angles", "order tracking needs the pulley angles recorded")
        kr = [k * o.revolutions for k in o.orders]
        if any(k <= 0 or abs(k - round(k)) > 1e-9 for k in kr):
            raise chk.fail("transient.orders.orders", f"each order must be a positive multiple of 1/{o.revolutions} "
                                                      f"(whole cycles per window of transient.orders.revolutions)")
        if max(o.orders) >= o.samples / 2:
            raise chk.fail("transient.orders.orders", f"must stay below {o.samples / 2:g} (half of "
                                                      f"transient.orders.samples)")
    if t.step is not None and t.min_step > t.step:
        raise chk.fail("transient.min_step", f"must be <= transient.step ({t.step:g} s)")
    if (t.accuracy is None) != (t.fmax is None):
        given, missing = ("accuracy", "fmax") if t.fmax is None else ("fmax", "accuracy")
        raise chk.fail(f"transient.{missing}", f"missing key: transient.{given} is given; give accuracy and "
                                               f"fmax together or neither")
    return t
