"""The shipped table of V-ribbed belt sections (`beltdyn/data/belt_sections.toml`): per rib the mass
per length, the axial stiffness EA, the bending stiffness EI, and the diameter offset from a pulley's
effective diameter to the belt's pitch line; each value with its source in the file."""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass, replace
from importlib import resources

from beltdyn.config.kinds import _Checker
from beltdyn.config.schema import Belt, Pulley


@dataclass(frozen=True, kw_only=True)
class BeltSection:
    """One section's values per rib (SI): rib_pitch m, mass_per_rib kg/m, EA_per_rib N, EI_per_rib
    N m^2, diameter_offset m (pitch diameter minus effective diameter); sources: value name -> source."""

    name: str
    rib_pitch: float
    mass_per_rib: float
    EA_per_rib: float
    EI_per_rib: float
    diameter_offset: float
    sources: tuple[tuple[str, str], ...]


VALUES = ("rib_pitch", "mass_per_rib", "EA_per_rib", "EI_per_rib", "diameter_offset")


@functools.cache
def belt_sections() -> dict[str, BeltSection]:
    """The shipped sections by name ("PH", "PJ", "PK", "PL", "PM")."""
    text = resources.files("beltdyn").joinpath("data", "belt_sections.toml").read_text(encoding="utf-8")
    table = tomllib.loads(text)
    return {name: BeltSection(name=name, **{v: float(entry[v]["value"]) for v in VALUES},
                              sources=tuple((v, str(entry[v]["source"])) for v in VALUES))
            for name, entry in table.items()}


def split_designation(section: str) -> tuple[int | None, str]:
    """"6PK" -> (6, "PK"); "PK" -> (None, "PK") (the rib count then comes from belt.ribs)."""
    digits = len(section) - len(section.lstrip("0123456789"))
    return (int(section[:digits]) if digits else None), section[digits:]


BELT_VALUES = (("EA", "EA_per_rib"), ("EI", "EI_per_rib"), ("mass_per_length", "mass_per_rib"))


def _resolve_belt(chk: _Checker, belt: Belt) -> Belt:
    """belt.section and belt.ribs -> EA, EI, mass_per_length where not given (given ones win);
    without a section all three are required. The section written back bare ("PK"), ribs set."""
    if belt.section is None:
        if belt.ribs is not None:
            raise chk.fail("belt.ribs", "belt.ribs needs belt.section (the V-ribbed section, e.g. \"PK\")")
        for name, _ in BELT_VALUES:
            if getattr(belt, name) is None:
                raise chk.fail(f"belt.{name}", f"missing key: give belt.{name}, or belt.section and belt.ribs")
        return belt
    ribs_in_name, bare = split_designation(belt.section.strip())
    known = belt_sections()
    if bare not in known:
        raise chk.fail("belt.section", f"unknown section {belt.section!r}; the known sections are "
                                       f"{', '.join(known)} (as \"PK\" with belt.ribs, or \"6PK\")")
    if ribs_in_name is not None and belt.ribs is not None and ribs_in_name != belt.ribs:
        raise chk.fail("belt.ribs", f"belt.section {belt.section!r} has {ribs_in_name} ribs, belt.ribs says "
                                    f"{belt.ribs}; give the count once")
    ribs = belt.ribs if belt.ribs is not None else ribs_in_name
    if not ribs:
        raise chk.fail("belt.ribs", f"missing key: belt.section {belt.section!r} needs the number of ribs "
                                    f"(belt.ribs = 6, or section = \"6{bare}\")")
    section = known[bare]
    values = {name: float(ribs * getattr(section, per_rib)) for name, per_rib in BELT_VALUES
              if getattr(belt, name) is None}
    return replace(belt, section=bare, ribs=ribs, derived=tuple(values), **values)


def _resolve_radii(chk: _Checker, belt: Belt, pulleys: tuple[Pulley, ...]) -> tuple[Pulley, ...]:
    """pulleys[i].effective_diameter -> radius = (d_e + the section's diameter offset) / 2; exactly one
    of radius and effective_diameter per pulley."""
    out = []
    for i, p in enumerate(pulleys):
        key = f"pulleys[{i}]"
        if p.effective_diameter is None:
            if p.radius is None:
                raise chk.fail(f"{key}.radius", "missing key: give radius (or effective_diameter with belt.section)")
            out.append(p)
            continue
        if p.radius is not None:
            raise chk.fail(f"{key}.effective_diameter", "give radius or effective_diameter, not both")
        if belt.section is None:
            raise chk.fail(f"{key}.effective_diameter", "effective_diameter needs belt.section (its diameter "
                                                        "offset to the belt's pitch line); or give radius")
        if p.side != "inside":
            raise chk.fail(f"{key}.effective_diameter", "effective_diameter is a grooved pulley's (side = "
                                                        "\"inside\"); give a backside pulley's radius at the "
                                                        "belt's pitch line")
        offset = belt_sections()[belt.section].diameter_offset
        out.append(replace(p, radius=0.5 * (p.effective_diameter + offset)))
    return tuple(out)
