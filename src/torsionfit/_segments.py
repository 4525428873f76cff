"""Torque series of a bench run: smoothing by sample index and monotone segments between
turning points. Shared by the data-only metrics and the fit's torque denoiser."""

import numpy as np


def moving_median(y: np.ndarray, width: int) -> np.ndarray:
    """Centred running median (removes isolated spikes before the polynomial smoother)."""
    if width <= 1 or y.size < width:
        return y.copy()
    half = width // 2
    padded = np.pad(y, half, mode="edge")
    return np.median(np.lib.stride_tricks.sliding_window_view(padded, width), axis=1)


def savgol_weights(width: int) -> np.ndarray:
    """Weights giving the centre value of a least-squares quadratic over ``width`` samples."""
    half = width // 2
    x = np.arange(-half, half + 1, dtype=float)
    return np.linalg.pinv(np.vander(x, 3, increasing=True))[0]


def savgol(y: np.ndarray, width: int) -> np.ndarray:
    """Quadratic Savitzky–Golay smoothing by sample index.

    By index, not by time: time stamps may repeat (benches quantise time), samples do not.
    A quadratic keeps ramps exact and rounds turning points less than a moving mean. The ends
    are padded by odd reflection, which continues a linear trend through them.
    """
    half = width // 2
    if half < 1 or y.size < 2 * half + 2:
        return y.copy()
    left = 2.0 * y[0] - y[half:0:-1]
    right = 2.0 * y[-1] - y[-2 : -half - 2 : -1]
    padded = np.concatenate([left, y, right])
    return np.convolve(padded, savgol_weights(width)[::-1], mode="valid")


def default_window(n: int) -> int:
    """Default smoothing window (odd): about 1/400 of the run, at least 5 samples."""
    width = max(5, n // 400)
    return width if width % 2 else width + 1


# ----------------------------------------------------------------------------- segments


def turning_points(y: np.ndarray, threshold: float) -> list[int]:
    """Indices of the extremes of ``y`` confirmed by a retreat larger than ``threshold``.

    A zig-zag filter: a maximum counts only once the signal has fallen ``threshold`` below
    it (and a minimum likewise), so wiggles smaller than the threshold never split a ramp.
    """
    points: list[int] = []
    i_hi = i_lo = 0
    direction = 0  # +1 rising (looking for a maximum), −1 falling, 0 not yet known
    for i in range(1, y.size):
        value = y[i]
        if direction >= 0 and value > y[i_hi]:
            i_hi = i
        if direction <= 0 and value < y[i_lo]:
            i_lo = i
        if direction == 0:
            # The first extreme is a turning point only if the signal also came to it by
            # more than the threshold (else it is the start of the first ramp).
            if value - y[i_lo] > threshold:
                if y[0] - y[i_lo] > threshold:
                    points.append(i_lo)
                direction = 1
                i_hi = i_lo + int(np.argmax(y[i_lo : i + 1]))
            elif y[i_hi] - value > threshold:
                if y[i_hi] - y[0] > threshold:
                    points.append(i_hi)
                direction = -1
                i_lo = i_hi + int(np.argmin(y[i_hi : i + 1]))
        elif direction == 1 and y[i_hi] - value > threshold:
            points.append(i_hi)
            direction = -1
            i_lo = i
        elif direction == -1 and value - y[i_lo] > threshold:
            points.append(i_lo)
            direction = 1
            i_hi = i
    return points


def smooth_torque(tau: np.ndarray, width: int) -> tuple[np.ndarray, float]:
    """Smoothed torque (running median of 5, then :func:`savgol` over ``width`` samples) and σ,
    the noise left in it: the robust σ of the raw − smoothed residual times the filter's noise
    gain."""
    smooth = savgol(moving_median(tau, 5), width)
    resid = tau - smooth
    sigma = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    sigma *= float(np.sqrt(np.sum(savgol_weights(width) ** 2))) if width > 1 else 1.0
    return smooth, sigma


def split_monotone(smooth: np.ndarray, threshold: float) -> list[tuple[int, int, int]]:
    """Monotone segments ``[(start, stop, direction), ...]`` of ``smooth`` between its
    :func:`turning_points` (``stop`` inclusive, consecutive segments share their turning point,
    direction ±1)."""
    bounds = [0, *turning_points(smooth, threshold), smooth.size - 1]
    return [(a, b, 1 if smooth[b] > smooth[a] else -1) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


#: the fit's ramps (torque denoiser, latent torque knots, errors-in-variables branches): a turning
#: point needs a retreat of 2 % of the torque range (or 8 σ of noise). With 10 % the ±4 N·m play
#: ramps of a measured ±40 N·m file (a 10 % retreat) were no ramps of their own: the denoiser
#: smoothed across their reversals (corners rounded by 0.3 N·m, the torque's sd overstated 20×)
#: and no latent knot sat at them
FIT_REVERSAL_FRACTION = 0.02


def monotone_segments(torque_Nm, *, reversal_fraction: float = 0.10, noise_sigmas: float = 8.0):
    """Smoothed torque and its monotone segments ``[(start, stop, direction), ...]`` (``stop``
    inclusive, consecutive segments share their turning point). A turning point needs a
    retreat larger than ``max(reversal_fraction × range, noise_sigmas × σ)``."""
    tau = np.asarray(torque_Nm, float)
    smooth, sigma = smooth_torque(tau, default_window(tau.size))
    threshold = max(reversal_fraction * float(np.ptp(smooth)), noise_sigmas * sigma, 1e-300)
    return smooth, split_monotone(smooth, threshold)


def fit_ramps(torque_Nm) -> list[tuple[int, int, int]]:
    """The fit's ramps of a torque series: :func:`monotone_segments` at
    :data:`FIT_REVERSAL_FRACTION`."""
    return monotone_segments(torque_Nm, reversal_fraction=FIT_REVERSAL_FRACTION)[1]
