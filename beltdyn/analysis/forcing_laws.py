"""The stepper's forcing laws, compiled with numba (`integrator`'s forcing and constraint parts call them):
the prescribed rotation law of a pulley (`rotation_state`: a nominal speed ramp and a fluctuation, with its
smoothstep fade-in), the load signals (`signal_values`: ramped harmonics or tables) and their table
interpolation (`table_value`, numpy's np.interp exactly, held equal by tests/test_transient.py).
"""

from __future__ import annotations

import numpy as np

from beltdyn.jitcache import configure, kernel_options

configure()  # where numba caches the kernels (the package folder, else a user cache folder): before numba loads
from numba import njit  # noqa: E402

KERNEL = kernel_options()  # the njit options of this module's kernels (numba loaded)


@njit(**KERNEL)
def table_value(xp, fp, a, b, x):
    """np.interp(x, xp[a:b], fp[a:b]) for one x, xp increasing (as numpy computes it: the end values
    outside, fp at a sample time, else the slope times the distance from the sample below; np.interp
    itself would make the cached stepper load numba's array modules, see `stepper_data.Work`)."""
    if b - a == 1 or x < xp[a]:
        return fp[a]
    if x >= xp[b - 1]:
        return fp[b - 1]
    lo, hi = a, b - 1  # xp[lo] <= x < xp[hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    if xp[lo] == x:
        return fp[lo]
    slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo])
    val = slope * (x - xp[lo]) + fp[lo]
    if val != val:  # NaN one way: the other (numpy's rule)
        val = slope * (x - xp[lo + 1]) + fp[lo + 1]
        if val != val and fp[lo] == fp[lo + 1]:
            val = fp[lo]
    return val


@njit(**KERNEL)
def signal_values(F, t, out):
    """out[i] = ramp_i(t) * (c + A sin(2 pi f t + phi)) or table interpolation; params (n, 5) = c, A, f, phi, T_ramp."""
    params = F.sig_params
    for i in range(params.shape[0]):
        a, b = F.tab_ptr[i], F.tab_ptr[i + 1]
        if b > a:
            val = table_value(F.tab_t, F.tab_v, a, b, t)
        else:
            val = params[i, 0] + params[i, 1] * np.sin(2.0 * np.pi * params[i, 2] * t + params[i, 3])
        tr = params[i, 4]
        if tr > 0.0 and t < tr:
            val *= t / tr
        out[i] = val


@njit(**KERNEL)
def smoothstep(t, tr):
    """C1 fade-in 3x^2 - 2x^3 over [0, tr] and its first two derivatives."""
    if tr <= 0.0 or t >= tr:
        return 1.0, 0.0, 0.0
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    x = t / tr
    return x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x) / tr, (6.0 - 12.0 * x) / (tr * tr)


@njit(**KERNEL)
def rotation_state(rot, t):
    """Prescribed rotation: (nominal angle, speed, acceleration), (fluctuation angle, speed, acceleration).

    rot = [speed Omega, ramp T_r, angle amplitude A, speed amplitude B, frequency f, phase phi, fade T_f,
           static angle offset, engine order k, start speed Omega_0] (the offset is added to the prescribed DOF
           by the caller). Nominal: speed ramps linearly from Omega_0 to Omega over T_r. Fluctuation:
    w(t) * A sin(psi) for an angle amplitude, or the angle whose speed is w(t) * B sin(psi) (zero at t=0 for
    the unfaded part), w(t) the smoothstep fade-in over T_f. The phase psi = 2 pi f t + phi, or with an engine
    order k > 0 psi = k theta_nominal(t) + phi (it follows the ramp). With an order, a speed amplitude is the
    angle (B / (k Omega)) (cos phi - cos psi): speed amplitude B at the mean speed, in proportion below.
    """
    om, tr, A, B, f, phi, tf, k, om0 = rot[0], rot[1], rot[2], rot[3], rot[4], rot[5], rot[6], rot[8], rot[9]
    if tr > 0.0 and t < tr:
        th, thd, thdd = om0 * t + 0.5 * (om - om0) * t * t / tr, om0 + (om - om0) * t / tr, (om - om0) / tr
    else:
        th, thd, thdd = om * (t - 0.5 * tr) + 0.5 * om0 * tr, om, 0.0
    if k > 0.0:
        psi, psid, psidd = k * th + phi, k * thd, k * thdd
    else:
        psi, psid, psidd = 2.0 * np.pi * f * t + phi, 2.0 * np.pi * f, 0.0
    if A != 0.0:
        g = A * np.sin(psi)
        gd = A * psid * np.cos(psi)
        gdd = A * (psidd * np.cos(psi) - psid * psid * np.sin(psi))
    elif B != 0.0 and (k > 0.0 or f > 0.0):
        c = B / (k * om) if k > 0.0 else B / psid
        g = c * (np.cos(phi) - np.cos(psi))
        gd = c * psid * np.sin(psi)
        gdd = c * (psidd * np.sin(psi) + psid * psid * np.cos(psi))
    else:
        g, gd, gdd = 0.0, 0.0, 0.0
    s, sd, sdd = smoothstep(t, tf)
    return th, thd, thdd, s * g, sd * g + s * gd, sdd * g + 2.0 * sd * gd + s * gdd
