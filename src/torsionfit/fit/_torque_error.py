"""How the error of the denoised drive torque moves the measured angle: the errors-in-variables
variance of each hysteresis sample, read from the data.

The model is driven by the denoised measured torque τ̂, whose error (sd s_i, from the smoother)
shifts a sample along its loop branch. Where the loop is steep (the gap crossed near zero
torque, the end of a friction plateau) a small torque error is a large angle error. The angle
that error can move is taken from the *measured* branch: θ smoothed along each monotone ramp,
as a function of τ̂, and the half-difference of that branch over τ̂_i ± s_i,

    var_i = (½ |θ̃(τ̂_i + s_i) − θ̃(τ̂_i − s_i)|)².

From the data, not from the model: a variance linearised in the model's own slope,
(dθ̂/dτ̂)² s_i², has no ceiling and is the model's to choose — on measured loops the posterior's
optimum steepened the loop where it misfit (flat plateaus after each reversal, then
near-vertical drops) and booked the misfit as torque error instead of fitting it. A secant over
the data's branch is bounded by the angle the data actually move across ±s_i, the same for
every model fitted to the file (so their likelihoods compare), and constant in the parameters.
"""

import numpy as np

from .._segments import fit_ramps
from ._denoise import gcv_half_width, local_linear


def angle_variance_from_torque_error(angle_rad, torque_Nm, denoised_Nm, torque_var_Nm2) -> np.ndarray:
    """Per-sample angle variance (rad²) that the denoised torque's error (variance
    ``torque_var_Nm2`` per sample) puts into a hysteresis run's measured angle; the ramps are
    the monotone segments of the measured ``torque_Nm``."""
    theta = np.asarray(angle_rad, float)
    tau_hat = np.asarray(denoised_Nm, float)
    sd = np.sqrt(np.maximum(np.asarray(torque_var_Nm2, float), 0.0))
    out = np.zeros(theta.size)
    if theta.size < 7 or not np.any(sd > 0):
        return out
    for start, stop, direction in fit_ramps(np.asarray(torque_Nm, float)):
        sl = slice(start, stop + 1)
        if stop - start < 3:
            continue
        # the branch as a function of torque: θ smoothed along the ramp (by index, its window
        # by cross-validation, so a sharp gap crossing stays sharp), τ̂ made strictly increasing
        branch = local_linear(theta[sl], gcv_half_width(theta[sl]))
        t = np.maximum.accumulate(direction * tau_hat[sl])
        t = t + 1e-12 * (np.ptp(t) + 1.0) * np.arange(t.size)
        s = sd[sl]
        half = 0.5 * np.abs(np.interp(t + s, t, branch) - np.interp(t - s, t, branch))
        out[sl] = half**2
    return out
