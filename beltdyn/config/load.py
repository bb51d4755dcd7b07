"""Loading: a TOML file read, overridden and validated (`load_config`); a parsed description
validated, the declared keys first, then the checks that involve several keys (`config_from_dict`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

from beltdyn.config.kinds import _Checker, _parse
from beltdyn.config.schema import DriveConfig
from beltdyn.config.checks import (_check_length_tension, _check_pulleys, _check_response, _check_spans,
                                   _check_spring_tension, _check_static_torques, _check_transient)
from beltdyn.config.overrides import apply_override, parse_toml_file
from beltdyn.config.sections import _resolve_belt, _resolve_radii


def load_config(path: Path | str, overrides: tuple[str, ...] | list[str] = ()) -> DriveConfig:
    """Read, override and validate a drive description."""
    path = Path(path)
    raw = parse_toml_file(path)
    for assignment in overrides:
        apply_override(raw, assignment, file=str(path))
    return config_from_dict(raw, file=str(path))


def config_from_dict(raw: dict[str, Any], *, file: str = "<config>", tables: dict[str, bytes] | None = None
                     ) -> DriveConfig:
    """Validate a parsed TOML drive description: the declared keys first, then the checks that
    involve several keys. tables: the CSV tables' bytes by the name the configuration gives them
    (`table_bytes`), for a process that cannot read them next to `file` (a remote sweep worker)."""
    chk = _Checker(file, tables)
    cfg = _parse(chk, "", raw, DriveConfig)
    belt = _resolve_belt(chk, cfg.belt)
    pulleys = _check_pulleys(chk, raw["pulleys"], _resolve_radii(chk, belt, cfg.pulleys))
    adjustable = any(p.adjustable for p in pulleys)
    tension = cfg.tension
    if "mode" not in raw.get("tension", {}):  # default: move the adjustable pulley if there is one
        tension = replace(tension, mode="adjust" if adjustable else "prestrain")
    if tension.target is not None and tension.mode == "adjust" and not adjustable:
        raise chk.fail("tension.mode", "mode \"adjust\" needs one pulley with adjustable = true "
                       "(or use mode = \"prestrain\")")
    if tension.mode == "spring":
        _check_spring_tension(chk, tension, pulleys)
    if tension.mode == "length":
        _check_length_tension(chk, tension, pulleys)
    _check_static_torques(chk, cfg.static, pulleys)
    _check_spans(chk, cfg.spans, pulleys)
    transient = cfg.transient
    if transient is not None:
        transient = _check_transient(chk, transient, pulleys, file)
    if cfg.response is not None:
        _check_response(chk, cfg.response, pulleys)
    if cfg.running is not None and cfg.running.belt_speed is not None and cfg.running.driver_speed is not None:
        raise chk.fail("running.driver_speed", "give either running.belt_speed or running.driver_speed, not both")
    return replace(cfg, belt=belt, pulleys=pulleys, tension=tension, transient=transient, source=file)
