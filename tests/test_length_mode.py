"""tension.mode = "length" (issue 25, item 3): every centre as given, belt.length the undeformed length,
the tension an output.

Compared against: the closed form of the bar law for the stretch lambda = L_path / L0 (rigid wraps: the
belt stretched uniformly onto its path, T = N(lambda) = EA (lambda^2 - 1) lambda / 2), with the path
length of two pulleys by the open-belt formula 2 sqrt(d^2 - (R2 - R1)^2) + pi (R1 + R2) + 2 (R2 - R1) phi,
sin phi = (R2 - R1) / d, computed here independently of the layout code."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import config_from_dict
from beltdyn.errors import ConfigError
from beltdyn.model.barlaw import axial_force
from beltdyn.pipeline import analyse

ROOT = Path(__file__).resolve().parents[1]


def fixed_centre_drive(stretch: float) -> tuple[dict, float]:
    """The smoke drive with both centres fixed and a belt of length L_path / stretch; (raw, L_path)."""
    raw = tomllib.loads((ROOT / "configs" / "smoke" / "two_pulley.toml").read_text())
    raw["pulleys"][0].update(support="fixed", adjustable=False)
    del raw["pulleys"][0]["bearing_stiffness"], raw["pulleys"][0]["slide_direction"]
    raw["tension"] = {"mode": "length"}
    (x1, y1), (x2, y2) = raw["pulleys"][0]["center"], raw["pulleys"][1]["center"]
    r1, r2 = raw["pulleys"][0]["radius"], raw["pulleys"][1]["radius"]
    d = math.hypot(x2 - x1, y2 - y1)
    phi = math.asin((r2 - r1) / d)
    path = 2.0 * math.sqrt(d * d - (r2 - r1) ** 2) + math.pi * (r1 + r2) + 2.0 * (r2 - r1) * phi
    raw["belt"]["length"] = path / stretch
    return raw, path


@pytest.mark.parametrize("stretch", [1.0015, 1.006])
def test_the_tension_of_a_stretch_fit_belt_is_the_laws_closed_form(stretch):
    raw, path = fixed_centre_drive(stretch)
    run = analyse(config_from_dict(raw))
    assert run.layout.belt_length == pytest.approx(path, rel=1e-12)
    lam = path / raw["belt"]["length"]
    T = axial_force(lam, raw["belt"]["EA"])
    np.testing.assert_allclose(run.static.span_tension, T, rtol=1e-9)
    assert run.static.mean_tension == pytest.approx(T, rel=1e-9)
    assert run.static.tension_mode == "geometry"  # the tension an output of the geometry


def test_a_slack_or_far_too_short_belt_is_a_named_error():
    raw, path = fixed_centre_drive(0.999)  # longer than its path: slack
    with pytest.raises(ConfigError) as slack:
        analyse(config_from_dict(raw))
    assert slack.value.key == "belt.length" and "slack" in str(slack.value) and slack.value.exit_code == 2
    raw, path = fixed_centre_drive(1.25)  # 25 % strain to fit: a wrong length
    with pytest.raises(ConfigError) as short:
        analyse(config_from_dict(raw))
    assert short.value.key == "belt.length" and "1.25" in str(short.value) and short.value.exit_code == 2
    raw, path = fixed_centre_drive(1.19)  # 19 %: fitted
    assert analyse(config_from_dict(raw)).static.mean_tension > 0.0


def test_length_mode_takes_no_target_and_no_adjustable_pulley():
    raw, _ = fixed_centre_drive(1.005)
    with_target = copy.deepcopy(raw)
    with_target["tension"]["target"] = 200.0
    with pytest.raises(ConfigError, match="mode = \"length\"") as e:
        config_from_dict(with_target)
    assert e.value.key == "tension.target"
    adjustable = tomllib.loads((ROOT / "configs" / "smoke" / "two_pulley.toml").read_text())
    adjustable["tension"] = {"mode": "length"}
    with pytest.raises(ConfigError) as e:
        config_from_dict(adjustable)
    assert e.value.key == "pulleys[0].adjustable"
