"""Span ends on their tangent points after the static solve (issue 25, item 1): the material a pulley's
rotation moved is carried into the spans' reference lengths (`relay.settled_reference`), so the end
nodes sit on the tangent points of the solved geometry. Compared against the tangent geometry laid
out independently at the solved centres (`geometry.relay`) and the pulleys' circles."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beltdyn.analysis.static.relay import span_end_points
from beltdyn.config import config_from_dict, load_config
from beltdyn.model.geometry import relay
from beltdyn.pipeline import analyse

from test_system import TWO_ARMS

FEAD = Path(__file__).resolve().parents[1] / "configs" / "examples" / "fead_4cyl.toml"


def _drives():
    fead = load_config(FEAD)  # loaded: its [[static.torque]] turn the accessories
    assert any(t.value for t in fead.static.torque)
    return [("fead", fead), ("fead-all-spring", load_config(FEAD, [f'spans.{n}.model="spring"' for n in fead.span_names])),
            ("two-arms", config_from_dict(TWO_ARMS))]


@pytest.mark.parametrize("name,cfg", _drives(), ids=[d[0] for d in _drives()])
def test_span_ends_sit_on_the_tangent_points_of_the_solved_geometry(name, cfg):
    run = analyse(cfg)
    st, system = run.static, run.system
    lay = relay(system.layout, st.pulley_center)  # the tangent geometry at the solved centres
    ends = span_end_points(system, st.q)  # (n, 2, 2)
    chord = np.hypot(*(ends[:, 1] - ends[:, 0]).T)
    np.testing.assert_allclose(chord, lay.span_length, rtol=1e-9, atol=0.0)
    n = lay.n
    for s_ in range(n):  # start on pulley s, end on pulley s + 1
        for k, j in ((0, s_), (1, (s_ + 1) % n)):
            r = float(np.hypot(*(ends[s_, k] - st.pulley_center[j])))
            assert abs(r - lay.radius[j]) <= 1e-9 * lay.radius[j], (name, s_, k)
    assert np.abs(lay.radius * st.pulley_rotation).max() <= 1e-9 * lay.span_length.min()
    if cfg.tension.mode in ("adjust", "spring"):  # the belt's undeformed length conserved: spans and wraps
        wraps = st.wraps.stress_free_length  # (creep wraps, the default; R beta with rigid wraps)
        assert system.belt.reference_length.sum() + wraps.sum() == pytest.approx(cfg.belt.length, rel=1e-12)


@pytest.mark.parametrize("shrink", [1e-4, 3e-3, 0.05])
def test_settled_tension_meets_its_definition(shrink):
    """settled_tension: tensions T_ref + split whose stretches (EA eps lambda = T, solved here by numpy's
    cubic roots, independently of the bar law's Newton) hold sum L_s / lambda_s = the reference total."""
    from beltdyn.analysis.static.tension import settled_tension

    EA = 1.2e5
    L = np.array([0.31, 0.084, 0.22, 0.15, 0.4])
    split = np.array([0.0, 120.0, -40.0, 35.0, 80.0])
    total = float(L.sum()) * (1.0 - shrink)
    T = settled_tension(L, split, total, EA)
    np.testing.assert_allclose(T - T[0], split - split[0], rtol=0.0, atol=1e-9 * EA)
    lam = np.array([max(r.real for r in np.roots([1.0, 0.0, -1.0, -2.0 * t / EA]) if abs(r.imag) < 1e-12) for t in T])
    assert float((L / lam).sum()) == pytest.approx(total, rel=1e-13)
