"""Belt sections (issue 29): `belt.section` / `belt.ribs` take EA, EI and the mass per length from the
shipped table (beltdyn/data/belt_sections.toml, read here independently with tomllib), given values
win, an unknown section is refused naming the known ones (exit 2 at the command line), and
`pulleys[i].effective_diameter` becomes the radius (d_e + the section's diameter offset) / 2."""

from __future__ import annotations

import subprocess
import tomllib
from pathlib import Path

import pytest

from beltdyn.config import apply_override, config_from_dict, config_to_dict, load_config, resolved_toml, with_overrides
from beltdyn.errors import ConfigError
from processes import BELTDYN  # tests/processes.py

ROOT = Path(__file__).resolve().parents[1]
TABLE = ROOT / "beltdyn" / "data" / "belt_sections.toml"
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"


def shipped() -> dict:
    return tomllib.loads(TABLE.read_text(encoding="utf-8"))


def fead_raw(**belt) -> dict:
    """The example FEAD with its belt table replaced by `belt` (length kept)."""
    raw = tomllib.loads(FEAD.read_text(encoding="utf-8"))
    raw["belt"] = {"length": raw["belt"]["length"], **belt}
    return raw


def test_every_value_has_its_source_and_sections_are_the_iso_ones():
    table = shipped()
    assert set(table) == {"PH", "PJ", "PK", "PL", "PM"}
    for name, entry in table.items():
        for value in ("rib_pitch", "mass_per_rib", "EA_per_rib", "EI_per_rib", "diameter_offset"):
            assert entry[value]["value"] > 0, (name, value)
            assert len(entry[value]["source"]) > 10, (name, value)
    # ISO 9982 rib spacings (mm)
    assert {n: e["rib_pitch"]["value"] * 1e3 for n, e in table.items()} == \
        pytest.approx({"PH": 1.60, "PJ": 2.34, "PK": 3.56, "PL": 4.70, "PM": 9.40})


@pytest.mark.parametrize("name", ["PH", "PJ", "PK", "PL", "PM"])
@pytest.mark.parametrize("form", ["bare", "prefixed"])
def test_every_section_value_is_the_shipped_tables(name, form):
    ribs = 5
    belt = {"section": name, "ribs": ribs} if form == "bare" else {"section": f"{ribs}{name}"}
    cfg = config_from_dict(fead_raw(**belt), file="fead.toml")
    entry = shipped()[name]
    assert cfg.belt.EA == ribs * entry["EA_per_rib"]["value"]
    assert cfg.belt.EI == ribs * entry["EI_per_rib"]["value"]
    assert cfg.belt.mass_per_length == ribs * entry["mass_per_rib"]["value"]
    assert (cfg.belt.section, cfg.belt.ribs) == (name, ribs)
    assert set(cfg.belt.derived) == {"EA", "EI", "mass_per_length"}


def test_given_values_override_the_section():
    cfg = config_from_dict(fead_raw(section="6PK", EA=1.5e5, mass_per_length=0.12), file="fead.toml")
    entry = shipped()["PK"]
    assert cfg.belt.EA == 1.5e5 and cfg.belt.mass_per_length == 0.12
    assert cfg.belt.EI == 6 * entry["EI_per_rib"]["value"]
    assert cfg.belt.derived == ("EI",)


def test_resolved_toml_shows_what_was_used_and_round_trips():
    cfg = config_from_dict(fead_raw(section="6PK", EA=1.5e5), file="fead.toml")
    text = resolved_toml(cfg)
    entry = shipped()["PK"]
    EI, mass = 6 * entry["EI_per_rib"]["value"], 6 * entry["mass_per_rib"]["value"]
    # the section's values as a comment (in the hash), the keys as given
    assert f"[belt]\n# from belt.section 6 x PK (beltdyn/data/belt_sections.toml): EI = {EI!r}, " \
           f"mass_per_length = {mass!r}\n" in text
    assert tomllib.loads(text)["belt"] == {"length": cfg.belt.length, "EA": 1.5e5, "section": "PK", "ribs": 6,
                                           "wraps": "creep", "axial_law": "green-lagrange"}
    again = config_from_dict(tomllib.loads(text), file="fead.toml")
    assert resolved_toml(again) == text and again.belt == cfg.belt


@pytest.mark.parametrize("how", ["with_overrides", "resolved toml"])  # a sweep case: the resolved TOML + --set
def test_a_new_rib_count_takes_the_sections_values_anew_given_ones_kept(how):
    cfg = config_from_dict(fead_raw(section="6PK", EA=1.5e5), file="fead.toml")
    if how == "with_overrides":
        eight = with_overrides(cfg, ["belt.ribs=8"])
    else:
        raw = tomllib.loads(resolved_toml(cfg))
        apply_override(raw, "belt.ribs=8", file="fead.toml")
        eight = config_from_dict(raw, file="fead.toml")
    entry = shipped()["PK"]
    assert eight.belt.EI == 8 * entry["EI_per_rib"]["value"]
    assert eight.belt.mass_per_length == 8 * entry["mass_per_rib"]["value"]
    assert eight.belt.EA == 1.5e5
    assert with_overrides(cfg, ["belt.EI=0.03"]).belt.EI == 0.03  # an override of a section value wins


def test_plain_belt_unchanged_and_still_needs_its_values():
    cfg = load_config(FEAD)
    assert (cfg.belt.EA, cfg.belt.EI, cfg.belt.mass_per_length) == (120000.0, 0.015, 0.10)
    assert "section" not in config_to_dict(cfg)["belt"]
    with pytest.raises(ConfigError, match=r"belt\.EI: missing key"):
        config_from_dict(fead_raw(EA=1e5, mass_per_length=0.1), file="fead.toml")
    with pytest.raises(ConfigError, match=r"belt\.ribs: belt\.ribs needs belt\.section"):
        config_from_dict(fead_raw(EA=1e5, EI=0.01, mass_per_length=0.1, ribs=6), file="fead.toml")


def test_section_errors_name_the_key():
    with pytest.raises(ConfigError, match=r"belt\.section: unknown section '6PX'.*PH, PJ, PK, PL, PM"):
        config_from_dict(fead_raw(section="6PX"), file="fead.toml")
    with pytest.raises(ConfigError, match=r"belt\.ribs: missing key"):
        config_from_dict(fead_raw(section="PK"), file="fead.toml")
    with pytest.raises(ConfigError, match=r"belt\.ribs: .*has 6 ribs, belt\.ribs says 8"):
        config_from_dict(fead_raw(section="6PK", ribs=8), file="fead.toml")


def effective(raw: dict, index: int, d_e: float) -> dict:
    del raw["pulleys"][index]["radius"]
    raw["pulleys"][index]["effective_diameter"] = d_e
    return raw


def test_effective_diameter_conversion():
    raw = effective(fead_raw(section="6PK"), 0, 0.143)
    cfg = config_from_dict(raw, file="fead.toml")
    offset = shipped()["PK"]["diameter_offset"]["value"]
    assert cfg.pulleys[0].radius == pytest.approx(0.5 * (0.143 + offset), rel=1e-15)
    assert cfg.pulleys[0].radius == pytest.approx(0.0725, rel=1e-12)  # 143 mm + 2 mm (ISO 9981) = 145 mm
    written = config_to_dict(cfg)["pulleys"][0]
    assert written["effective_diameter"] == 0.143 and "radius" not in written
    assert config_from_dict(tomllib.loads(resolved_toml(cfg)), file="f").pulleys[0].radius == cfg.pulleys[0].radius


def test_effective_diameter_errors_name_the_key():
    raw = fead_raw(section="6PK")
    raw["pulleys"][0]["effective_diameter"] = 0.143
    with pytest.raises(ConfigError, match=r"pulleys\[0\]\.effective_diameter: give radius or effective_diameter"):
        config_from_dict(raw, file="fead.toml")
    raw = effective(fead_raw(EA=1e5, EI=0.01, mass_per_length=0.1), 0, 0.143)
    with pytest.raises(ConfigError, match=r"pulleys\[0\]\.effective_diameter: effective_diameter needs belt\.section"):
        config_from_dict(raw, file="fead.toml")
    raw = fead_raw(section="6PK")
    del raw["pulleys"][1]["radius"]
    with pytest.raises(ConfigError, match=r"pulleys\[1\]\.radius: missing key"):
        config_from_dict(raw, file="fead.toml")
    backside = next(i for i, p in enumerate(fead_raw()["pulleys"]) if p.get("side") == "backside")
    with pytest.raises(ConfigError, match=rf"pulleys\[{backside}\]\.effective_diameter: .*backside"):
        config_from_dict(effective(fead_raw(section="6PK"), backside, 0.07), file="fead.toml")


def test_unknown_section_exits_2_listing_the_known_ones(tmp_path):
    text = FEAD.read_text(encoding="utf-8").replace("EA = 120000.0", 'section = "6PZ"\nEA = 120000.0')
    path = tmp_path / "drive.toml"
    path.write_text(text, encoding="utf-8")
    proc = subprocess.run([*BELTDYN, "geometry", str(path)], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 2
    message = (proc.stdout + proc.stderr).strip()
    assert "belt.section" in message and "PH, PJ, PK, PL, PM" in message and "Traceback" not in message
    assert len(message.splitlines()) == 1


def test_console_shows_the_section_values(tmp_path):
    text = FEAD.read_text(encoding="utf-8").replace("EI = 0.015", 'section = "6PK"')
    path = tmp_path / "drive.toml"
    path.write_text(text, encoding="utf-8")
    proc = subprocess.run([*BELTDYN, "geometry", str(path)], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "belt 6PK: EA 120000 N (given), EI 0.015 N m^2 (section), mass_per_length 0.1 kg/m (given)" \
        in " ".join(proc.stdout.split())
