"""Denoised torque to drive the friction state.

Raw torque increments carry sensor noise; at slow loading rates the noise per sample is
larger than the true increment, fakes tiny reversals and makes the Dahl state chatter. The
test protocol makes τ(t) piecewise monotone and smooth, so the torque is smoothed *within*
each monotone segment (between turning points, never across one) by a local-linear fit over
a wide window. Ramps are then reproduced without bias and with little noise, and the turning
points keep their corners (both one-sided fits extrapolate to the corner). A narrow smoother
across turning points would round them and leave noise correlated over its window: that
error goes straight into the angle and makes intervals overconfident (tested).
Smoothing is by sample index, not time, because benches quantise time (duplicate stamps).
"""

from typing import NamedTuple

import numpy as np

from .._segments import fit_ramps


def _windows(n: int, h: int):
    idx = np.arange(n)
    lo = np.clip(idx - h, 0, n)
    hi = np.clip(idx + h + 1, 0, n)
    count = hi - lo
    mean_i = (hi - 1 + lo) / 2.0
    sxx = count * (count**2 - 1) / 12.0  # Σ(i − ī)² over consecutive integers
    return idx, lo, hi, count, mean_i, sxx


def local_linear(y, half_width: int, return_leverage: bool = False):
    """Local-linear (Savitzky–Golay order 1) smooth by index; windows shrink at the ends.
    With ``return_leverage`` also the diagonal of the smoother matrix (for cross-validation)."""
    y = np.asarray(y, float)
    n = len(y)
    h = min(int(half_width), max(n - 1, 1))
    if n < 3 or h < 1:
        return (y.copy(), np.ones(n)) if return_leverage else y.copy()
    idx, lo, hi, count, mean_i, sxx = _windows(n, h)
    c = np.concatenate([[0.0], np.cumsum(y)])
    ci = np.concatenate([[0.0], np.cumsum(idx * y)])
    sum_y = c[hi] - c[lo]
    safe = np.maximum(sxx, 1e-300)
    slope = np.where(sxx > 0, (ci[hi] - ci[lo] - mean_i * sum_y) / safe, 0.0)
    fit = sum_y / count + slope * (idx - mean_i)
    if not return_leverage:
        return fit
    leverage = 1.0 / count + np.where(sxx > 0, (idx - mean_i) ** 2 / safe, 0.0)
    return fit, leverage


def gcv_half_width(y, candidates=None) -> int:
    """Half-width by generalised cross-validation, mean(r²)/(1 − mean(L_ii))², with the
    one-standard-error rule: the widest window whose score is within √(2/n) (the relative
    sampling spread of a mean square) of the minimum. On a straight ramp the scores are flat
    and the widest window (the exact line, least noise) wins; on a curved ramp bias makes
    wide windows score clearly worse."""
    n = len(y)
    if candidates is None:
        candidates = sorted({int(round(v)) for v in np.geomspace(3, max(3, n), 12)})
    scores = {}
    for h in candidates:
        fit, lev = local_linear(y, h, return_leverage=True)
        dof = np.mean(lev)
        if dof < 1.0:
            scores[h] = np.mean((y - fit) ** 2) / (1.0 - dof) ** 2
    if not scores:
        return candidates[0]
    best = min(scores.values())
    return max(h for h, v in scores.items() if v <= best * (1.0 + np.sqrt(2.0 / n)))


def _line(idx, y):
    """Least-squares line through (idx, y) as (slope, intercept)."""
    slope, intercept = np.polyfit(idx, y, 1)
    return slope, intercept


#: samples next to a turning point left out of each ramp's fit (the noisy index of the
#: turning point may put a sample of the next ramp into this one)
TRIM = 5


class RampLines(NamedTuple):
    """Which ramp's smoother each denoised sample is read from, and that ramp's noise: the
    low-frequency part of the denoised torque's error is one line per ramp (its level and tilt
    over the ramp's core), correlated along the whole ramp, not sample by sample."""

    ramp: np.ndarray  # (n,) index of the ramp whose smoother (or end line) gives the sample
    core_first: np.ndarray  # (K,) first sample of each ramp's core (its smoothed samples)
    core_last: np.ndarray  # (K,) last sample of each ramp's core
    noise_var_Nm2: np.ndarray  # (K,) the raw torque noise variance of each ramp, N·m²


def denoise_torque(torque_Nm, segment_fraction: float | None = None, return_lines: bool = False):
    """Torque smoothed within each monotone segment, N·m (and, with ``return_lines``, the
    variance of each smoothed sample, N·m², from the ramp's noise and the smoother's leverage,
    and the :class:`RampLines` each sample is read from).

    Each ramp, less ``TRIM`` samples next to each turning point, is smoothed by a local-linear
    fit whose half-width is chosen by generalised cross-validation (or fixed at
    ``segment_fraction`` of the ramp). Around each turning point the two ramps' end lines
    (over their smoothing windows) are extended and the corner is their intersection: the
    smaller of the two at a peak, the larger at a trough.
    """
    tau = np.asarray(torque_Nm, float)
    n = tau.size
    if n < 7:
        lines = RampLines(np.zeros(n, int), np.zeros(0, int), np.zeros(0, int), np.zeros(0))
        return (tau.copy(), np.zeros(n), lines) if return_lines else tau.copy()
    segments = fit_ramps(tau)
    out = tau.copy()
    var = np.zeros(n)
    ramp = np.zeros(n, int)
    ends = []  # per segment: (core start, core stop, width, first line, last line)
    for k, (start, stop, _) in enumerate(segments):
        lo = start + (TRIM if k > 0 else 0)
        hi = stop - (TRIM if k < len(segments) - 1 else 0)
        if hi - lo < 6:  # too short to trim: use it whole
            lo, hi = start, stop
        core = tau[lo:hi + 1]
        if segment_fraction is None:
            w = gcv_half_width(core)
        else:
            w = max(3, int(segment_fraction * core.size))
        fit, leverage = local_linear(core, w, return_leverage=True)
        out[lo:hi + 1] = fit
        ramp[lo:hi + 1] = k
        noise_var = np.mean((core - fit) ** 2) / max(1.0 - np.mean(leverage), 1e-3)
        var[lo:hi + 1] = noise_var * leverage
        m = min(core.size, 2 * w + 1)
        idx = np.arange(lo, hi + 1)
        ends.append((lo, hi, w, _line(idx[:m], core[:m]), _line(idx[-m:], core[-m:]), noise_var, idx[:m], idx[-m:]))
    for k in range(len(segments) - 1):
        direction = segments[k][2]
        _, a_hi, wa, _, (sa, ia), var_a, _, ia_idx = ends[k]
        b_lo, _, wb, (sb, ib), _, var_b, ib_idx, _ = ends[k + 1]
        pad = min(wa, wb, 4 * TRIM)
        i = np.arange(max(0, a_hi - pad), min(n - 1, b_lo + pad) + 1)
        left, right = sa * i + ia, sb * i + ib
        use_left = (left <= right) if direction > 0 else (left >= right)
        out[i] = np.where(use_left, left, right)
        var[i] = np.where(use_left, _line_variance(i, ia_idx, var_a), _line_variance(i, ib_idx, var_b))
        ramp[i] = np.where(use_left, k, k + 1)
    lines = RampLines(ramp, np.array([e[0] for e in ends]), np.array([e[1] for e in ends]), np.array([e[5] for e in ends]))
    return (out, var, lines) if return_lines else out


def _line_variance(i, idx, noise_var):
    """Variance of a least-squares line through samples at ``idx``, evaluated at ``i``."""
    mean = idx.mean()
    sxx = max(float(np.sum((idx - mean) ** 2)), 1e-300)
    return noise_var * (1.0 / idx.size + (i - mean) ** 2 / sxx)
