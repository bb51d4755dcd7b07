"""The resolved configuration: defaults filled in, as a TOML-ready dict (`config_to_dict`), as TOML
text (`resolved_toml`) and its hash (`config_hash`); overrides on a loaded config (`with_overrides`)."""

from __future__ import annotations

import hashlib
from typing import Any

from beltdyn.config.kinds import _dump
from beltdyn.config.schema import DriveConfig
from beltdyn.config.overrides import apply_override
from beltdyn.config.load import config_from_dict


def config_to_dict(cfg: DriveConfig, *, section_values: bool = True) -> dict[str, Any]:
    """The resolved configuration (defaults filled in) as a TOML-ready dict. The belt's values taken
    from belt.section are written (what was used) unless `section_values` is false (then a changed
    section or rib count gives them anew); a pulley given by its effective_diameter is written by it
    (its radius follows from the section)."""
    out = _dump(cfg)
    for p, d in zip(cfg.pulleys, out["pulleys"]):
        if p.support != "bearing":  # one stiffness (a slide's, or none): written as one number
            d["bearing_stiffness"] = p.bearing_stiffness[0]
        if p.effective_diameter is not None:
            del d["radius"]
    if not section_values:
        for name in cfg.belt.derived:
            del out["belt"][name]
    return out


def resolved_toml(cfg: DriveConfig) -> str:
    import tomli_w

    return tomli_w.dumps(config_to_dict(cfg))


def config_hash(cfg: DriveConfig) -> str:
    return hashlib.sha256(resolved_toml(cfg).encode()).hexdigest()


def with_overrides(cfg: DriveConfig, assignments: list[str] | tuple[str, ...]) -> DriveConfig:
    """A new config with dotted-key overrides applied (used by sweeps)."""
    renews = any(a.split("=", 1)[0].strip() in ("belt.section", "belt.ribs") for a in assignments)
    raw = config_to_dict(cfg, section_values=not renews)  # a new section or rib count: its values anew
    for a in assignments:
        apply_override(raw, a, file=cfg.source)
    return config_from_dict(raw, file=cfg.source)
