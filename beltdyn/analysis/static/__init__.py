"""Nonlinear static equilibrium: Newton with load stepping and line search.

Residual (reduced coordinates q, DESIGN section 2, paper Eq. 24 without inertia):
    R(q) = f_int(q) + k_s q - p - lambda f_g,
f_int the belt's internal force (Eqs. 14, 17) mapped through the joints, k_s the bearing springs
(Eq. 21) with preload p, f_g the weight (Eq. 8), lambda the load factor. The driver pulley's rotation
is held (it reacts the applied torques and removes the belt's rigid rotation). With tension mode
"adjust" the equation of the adjustable pulley's slide is replaced by  T(q) - T_target = 0,  T the
length-weighted mean true axial force of the spans: moving the pulley sets the tension and the
bearing spring's preload follows from the slide equation afterwards; the travel it takes is held to
the pulley's slide_range (a SolverError names the pulley, the travel needed and the limit).

Convergence is measured per DOF group (`ResidualScales`): span rows against the tension scale,
rotation rows against the torque scale tension x pulley radius, translation rows against the forces
on the pulley (belt pull, weight, the bearing spring's force from the displacement, not a constant
preload), each plus the belt's round-off floor; err <= 1 means converged.

Solved geometry (`solve_static_on_solved_geometry`, what `pipeline.analyse` runs). One system keeps
the tangent points of its layout: a pulley that moves in the solve (the tension travel, a bearing's
deflection) meets its spans off tangent, and a free pulley's two span tensions then differ. So the
belt is laid out anew at the solved pulley centres (`geometry.relay`), the system rebuilt and solved
again until the pulleys stay where they are laid (movement <= tolerance x the shortest span; one or
two passes with the predictor, a few more when bearings deflect). The belt's stress-free state: in
mode "adjust" it is the belt of undeformed length L0 over spans and wraps, the wraps unstretched
(DESIGN section 2: spans stress-free in the L0 geometry, the tension from moving the pulley); where
a tangent point moves along its pulley, that arc of belt passes between span and wrap
(`carried_reference`), so sum(span reference lengths) + sum(R_j wrap_j) = L0 on every layout, and
the bordered Newton meets the target on the final one. In mode "prestrain" the spans' common stretch
is iterated (secant) until the mean tension meets the target with every pulley free on its bearing.
The pulley rotations at equilibrium are belt moved over the pulleys: they are carried into the spans'
reference lengths (`relay.settled_reference`, the wrap unstretched, the belt's undeformed length kept)
and the drive solved again with the pulleys unturned, so the span ends sit on their tangent points and
the dynamics start from rotations 0 (docs/wraps.md). The result carries the wraps' creep state
(`model.wraps`: slip and adhesion arcs, rim speed ratios, creep losses) from the solved span tensions.
With creep wraps (belt.wraps, the default) the wraps' stress-free length takes the place of their arc
length in the belt's budget (sum of the spans' references + sum of the wraps' = L0): in the rigid-belt
prediction (`tension.settled_budget`) and checked at the equilibrium (`tension.budget_excess`, a secant
step on the spans' reference total where it misses; docs/wraps.md).

Modules, by job: `newton` (the static equations of one layout and their Newton solve: predictor,
residual scales, budget, load steps, continuations, the bordered tension step), `tension` (the belt's
length and tension over layouts: carried reference lengths, conserved tension, the torques' split,
the prestrain secant), `arms` (the predicted first layout: bearings deflected, arms balanced),
`relay` (the passes on the solved geometry), `result` (the result, its outputs and the checks).

Public API: `StaticResult`, `solve_static`, `solve_equilibrium`, `solve_static_on_solved_geometry`,
`SolvedDrive`, `ResidualScales`, `Budget`, `carried_reference`, `torque_split`, `warm_start`.
"""

from beltdyn.analysis.static.newton import (EVALUATIONS_PER_ITERATION, Budget, ResidualScales, solve_equilibrium,
                                            solve_static)
from beltdyn.analysis.static.relay import MAX_PASSES, SolvedDrive, solve_static_on_solved_geometry, warm_start
from beltdyn.analysis.static.result import StaticResult
from beltdyn.analysis.static.tension import carried_reference, torque_split

__all__ = ["EVALUATIONS_PER_ITERATION", "MAX_PASSES", "Budget", "ResidualScales", "SolvedDrive", "StaticResult",
           "carried_reference", "solve_equilibrium", "solve_static", "solve_static_on_solved_geometry", "torque_split",
           "warm_start"]
