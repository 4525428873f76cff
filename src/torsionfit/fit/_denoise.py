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

import numpy as np

from .._segments import monotone_segments


def local_linear(y, half_width: int) -> np.ndarray:
    """Local-linear (Savitzky–Golay order 1) smooth by index; windows shrink at the ends."""
    y = np.asarray(y, float)
    n = len(y)
    h = min(int(half_width), (n - 1) // 2)
    if n < 3 or h < 1:
        return y.copy()
    idx = np.arange(n)
    lo = np.clip(idx - h, 0, n)
    hi = np.clip(idx + h + 1, 0, n)
    count = hi - lo
    c = np.concatenate([[0.0], np.cumsum(y)])
    ci = np.concatenate([[0.0], np.cumsum(idx * y)])
    sum_y = c[hi] - c[lo]
    sum_i = (hi - 1 + lo) * count / 2.0
    mean_i = sum_i / count
    sxx = count * (count**2 - 1) / 12.0  # Σ(i − ī)² over consecutive integers
    slope = np.where(sxx > 0, (ci[hi] - ci[lo] - mean_i * sum_y) / np.maximum(sxx, 1e-300), 0.0)
    return sum_y / count + slope * (idx - mean_i)


def _end_line(y, h, at_end: bool):
    """Least-squares line (slope, intercept in local index) through the first/last h samples."""
    n = len(y)
    h = max(2, min(h, n))
    idx = np.arange(n - h, n) if at_end else np.arange(h)
    slope, intercept = np.polyfit(idx, y[idx], 1)
    return slope, intercept


def denoise_torque(torque_Nm, segment_fraction: float = 0.125) -> np.ndarray:
    """Torque smoothed within each monotone segment, half-width ``segment_fraction`` of the
    segment (at least 3 samples), N·m.

    Around each turning point the two neighbouring ramps are extended as straight lines and
    the corner is their intersection: the smaller of the two at a peak, the larger at a
    trough. This keeps the corner sharp even when noise puts the detected turning point a
    few samples off the true one.
    """
    tau = np.asarray(torque_Nm, float)
    if tau.size < 7:
        return tau.copy()
    _, segments = monotone_segments(tau)
    out = np.zeros_like(tau)
    weight = np.zeros_like(tau)
    widths = []
    for start, stop, _ in segments:
        part = tau[start:stop + 1]
        h = max(3, int(segment_fraction * part.size))
        widths.append(h)
        out[start:stop + 1] += local_linear(part, h)
        weight[start:stop + 1] += 1.0
    out /= np.maximum(weight, 1.0)
    for k in range(len(segments) - 1):
        (a0, a1, d), (b0, b1, _) = segments[k], segments[k + 1]
        h = min(widths[k], widths[k + 1])
        sa, ia = _end_line(tau[a0:a1 + 1], 2 * h, at_end=True)
        sb, ib = _end_line(tau[b0:b1 + 1], 2 * h, at_end=False)
        lo, hi = max(a0, a1 - h), min(b1, b0 + h) + 1
        i = np.arange(lo, hi)
        left = sa * (i - a0) + ia
        right = sb * (i - b0) + ib
        out[lo:hi] = np.minimum(left, right) if d > 0 else np.maximum(left, right)
    return out
