"""Denoised torque to drive the friction state.

Raw torque increments carry sensor noise; at slow loading rates the noise per sample is
larger than the true increment, fakes tiny reversals and makes the Dahl state chatter. The
test protocol makes τ(t) smooth and piecewise monotone, so a local-linear smoother over the
sample index recovers it. Index, not time, because benches quantise time (duplicate stamps).
"""

import numpy as np


def default_half_width(n: int) -> int:
    """Half-width (samples) of the smoothing window: 0.5 % of the run, at least 3."""
    return max(3, int(round(0.005 * n)))


def denoise_torque(torque_Nm, half_width: int | None = None) -> np.ndarray:
    """Local-linear (Savitzky–Golay order 1) smooth of a torque series, N·m.

    A local line keeps ramps unbiased; at turning points the peak is rounded over about
    ``half_width`` samples, which is why the window is kept short relative to a step.
    """
    y = np.asarray(torque_Nm, float)
    n = len(y)
    h = default_half_width(n) if half_width is None else int(half_width)
    if n < 3 or h < 1:
        return y.copy()
    h = min(h, (n - 1) // 2)
    # Moving mean of y over a centred window; near the ends the window shrinks (no padding bias).
    c = np.concatenate([[0.0], np.cumsum(y)])
    idx = np.arange(n)
    lo = np.clip(idx - h, 0, n)
    hi = np.clip(idx + h + 1, 0, n)
    count = hi - lo
    mean = (c[hi] - c[lo]) / count
    # Local slope by least squares over the same window, centred on the window's mean index.
    ci = np.concatenate([[0.0], np.cumsum(idx * y)])
    sum_iy = ci[hi] - ci[lo]
    sum_i = (hi - 1 + lo) * count / 2.0
    mean_i = sum_i / count
    # Σ(i − ī)² over a run of consecutive integers of length m: m(m² − 1)/12
    sxx = count * (count**2 - 1) / 12.0
    sum_y = c[hi] - c[lo]
    slope = np.where(sxx > 0, (sum_iy - mean_i * sum_y) / np.maximum(sxx, 1e-300), 0.0)
    return mean + slope * (idx - mean_i)
