"""The resolved configuration: defaults filled in, as a TOML-ready dict (`config_to_dict`), as TOML
text (`resolved_toml`) and its hash (`config_hash`); overrides on a loaded config (`with_overrides`)."""

from __future__ import annotations

import hashlib
from typing import Any

from beltdyn.config.kinds import _dump
from beltdyn.config.schema import DriveConfig
from beltdyn.config.overrides import apply_override
from beltdyn.config.load import config_from_dict


def config_to_dict(cfg: DriveConfig) -> dict[str, Any]:
    """The resolved configuration (defaults filled in) as a TOML-ready dict. The belt's values that
    belt.section gave are left out (the section and rib count give them again, so an override of
    either gives them anew; `resolved_toml` shows them as a comment); a pulley given by its
    effective_diameter is written by it (its radius follows from the section)."""
    out = _dump(cfg)
    for p, d in zip(cfg.pulleys, out["pulleys"]):
        if p.support != "bearing":  # one stiffness (a slide's, or none): written as one number
            d["bearing_stiffness"] = p.bearing_stiffness[0]
        if p.effective_diameter is not None:
            del d["radius"]
    for name in cfg.belt.derived:
        del out["belt"][name]
    return out


def resolved_toml(cfg: DriveConfig) -> str:
    import tomli_w

    text = tomli_w.dumps(config_to_dict(cfg))
    belt = cfg.belt
    if not belt.derived:
        return text
    # what the section gave, shown (and hashed: a changed table changes the hash) but not a key
    used = ", ".join(f"{name} = {getattr(belt, name)!r}" for name in belt.derived)
    note = f"# from belt.section {belt.ribs} x {belt.section} (beltdyn/data/belt_sections.toml): {used}\n"
    return text.replace("[belt]\n", "[belt]\n" + note, 1)


def config_hash(cfg: DriveConfig) -> str:
    return hashlib.sha256(resolved_toml(cfg).encode()).hexdigest()


def with_overrides(cfg: DriveConfig, assignments: list[str] | tuple[str, ...]) -> DriveConfig:
    """A new config with dotted-key overrides applied (used by sweeps)."""
    raw = config_to_dict(cfg)
    for a in assignments:
        apply_override(raw, a, file=cfg.source)
    return config_from_dict(raw, file=cfg.source)
