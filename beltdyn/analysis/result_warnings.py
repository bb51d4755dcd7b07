"""What makes a result doubtful for the engineer, shared by the static and transient analyses: a strain
far beyond a belt's working strain, a span close to slack."""

from __future__ import annotations

import numpy as np

from beltdyn.model.barlaw import stretch_for_tension


STRAIN_WARNING = 0.05  # belt strain above which the constant-EA axial law is flagged (real belts: ~1 % at most)


SLACK_WARNING = 0.1  # a span whose smaller end tension is below this share of the mean tension is flagged


def strain_warning(T: float, EA: float, when: str = "") -> list[str]:
    """[a warning] if the largest span tension T (N) stretches the belt beyond STRAIN_WARNING, else [].
    when: where in a run (e.g. " at t = 0.2 s"), empty for a static result."""
    strain = stretch_for_tension(T, EA) - 1.0 if np.isfinite(T) and T > 0 else 0.0  # engineering strain
    if strain <= STRAIN_WARNING:
        return []
    return [f"the belt is stretched by {strain:.1%}{when} (tension {T:.4g} N on EA = {EA:.4g} N): far beyond a "
            f"belt's working strain, where the axial law (constant EA) no longer describes it; check "
            f"tension.target and belt.EA"]
