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
from ._denoise import RampLines, gcv_half_width, local_linear


def ramp_line_basis(lines: RampLines, torque_var_Nm2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The denoised torque's error split by correlation: per ramp a line (its level and its tilt
    across the ramp's core, correlated over every sample read from that ramp) for the latent
    torque correction, and the rest per sample.

    A ramp's smoother averages its raw noise; the mean and the linear trend of the denoised
    error along the ramp are those of a least-squares line through the core (variances
    σ²/n and σ²/Σ(i − ī)², independent), whatever the window. With the widest window (a straight
    ramp) that line *is* the whole error: every sample of the ramp moves with it. Counted sample
    by sample instead, as an independent variance of each, one ramp's error reads as n
    independent errors and the friction level's interval came out about 2.5× too narrow where
    the encoder's steps were the only angle noise.

    Returns (basis (n, 2K): per ramp its level column, 1, then its tilt column, (i − ī)/half the
    core's span — both in N·m of correction; prior sd of each column, N·m; the per-sample
    variance the lines leave, N·m², ≥ 0).
    """
    var = np.asarray(torque_var_Nm2, float)
    n, k = var.size, lines.core_first.size
    basis = np.zeros((n, 2 * k))
    sd = np.zeros(2 * k)
    line_var = np.zeros(n)
    rows = np.arange(n)
    for j in range(k):
        on = lines.ramp == j
        count = float(lines.core_last[j] - lines.core_first[j] + 1)
        half = max(0.5 * (count - 1.0), 1.0)
        tilt = (rows[on] - 0.5 * (lines.core_first[j] + lines.core_last[j])) / half
        level_var = lines.noise_var_Nm2[j] / count
        sxx = count * (count**2 - 1.0) / 12.0  # Σ(i − ī)² over consecutive samples
        tilt_var = lines.noise_var_Nm2[j] / sxx * half**2 if sxx > 0 else 0.0
        basis[on, 2 * j] = 1.0
        basis[on, 2 * j + 1] = tilt
        sd[2 * j], sd[2 * j + 1] = np.sqrt(level_var), np.sqrt(tilt_var)
        line_var[on] = level_var + tilt**2 * tilt_var
    return basis, sd, np.maximum(var - line_var, 0.0)


def torque_line_labels(n_columns: int) -> list[str]:
    """Labels of :func:`ramp_line_basis`' columns: ``[k].level``, ``[k].tilt`` per ramp k."""
    return [f"[{k // 2}].{'tilt' if k % 2 else 'level'}" for k in range(n_columns)]


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
