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
    """The resolved configuration (defaults filled in) as a TOML-ready dict."""
    out = _dump(cfg)
    for p, d in zip(cfg.pulleys, out["pulleys"]):
        if p.support != "bearing":  # one stiffness (a slide's, or none): written as one number
            d["bearing_stiffness"] = p.bearing_stiffness[0]
    return out


def resolved_toml(cfg: DriveConfig) -> str:
    import tomli_w

    return tomli_w.dumps(config_to_dict(cfg))


def config_hash(cfg: DriveConfig) -> str:
    return hashlib.sha256(resolved_toml(cfg).encode()).hexdigest()


def with_overrides(cfg: DriveConfig, assignments: list[str] | tuple[str, ...]) -> DriveConfig:
    """A new config with dotted-key overrides applied (used by sweeps)."""
    raw = config_to_dict(cfg)
    for a in assignments:
        apply_override(raw, a, file=cfg.source)
    return config_from_dict(raw, file=cfg.source)
