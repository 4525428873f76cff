"""Do the time stamps run at the rates the manifest declares?

A time column in ms read as s (or in min) leaves a file perfectly readable and every time-based
quantity wrong by 1000× (60×): the loading rate behind the rate-dependent friction, creep and
lags, the TE run's speed. Where the manifest declares a rate, the data give the same rate in
their own time stamps, so a declared rate the stamps contradict by more than
:data:`RATE_RATIO_LIMIT`× stops with one line naming the time column and the key:

- a hysteresis run's ``loading_rate_Nm_per_s`` against the median rate of its excursions
  between torque reversals (each at least :data:`REVERSAL_FRACTION` of the torque's range, so
  noise and small play cycles do not split them), each read between 10 % and 90 % of its span
  (holds at its ends do not count, holds within it slow it);
- a TE run's ``speed_rpm`` (or ``input_speed_rpm`` / ``ratio``) against the output angle's mean
  rate over the run.

``[instrument] sample_rate_Hz`` is not checked against a time column: a bench samples a TE
run by angle and a hysteresis run by time (the bundled campaigns do). A TE run without a time
column is timed by that rate, so there the rate is checked against the declared speed.

The limit leaves room for nominal rates, a start-up, holds and a sinusoidal ramp (its median
excursion rate is 2/π of the peak), and none for a unit: ms/s is 1000×, min/s 60×, rad/s
declared as rpm 9.5×.
"""

import math

import numpy as np

from .._errors import InputError

#: a rate the stamps give this many times off the declared one (either way) stops the run
RATE_RATIO_LIMIT = 4.0
#: a torque reversal counts when it turns back by this share of the torque's range
REVERSAL_FRACTION = 0.2
#: samples of the running median that keeps a spike (motor-current torque) from being a reversal
_SMOOTH_SAMPLES = 5


def _running_median(x: np.ndarray, width: int) -> np.ndarray:
    if x.size < width:
        return x
    pad = width // 2
    padded = np.concatenate([np.full(pad, x[0]), x, np.full(pad, x[-1])])
    return np.median(np.lib.stride_tricks.sliding_window_view(padded, width), axis=1)


def turning_points(torque_Nm: np.ndarray, threshold_Nm: float) -> list[int]:
    """Indices of the torque's reversals by more than ``threshold_Nm`` (peak detection with
    hysteresis), the first and last sample included."""
    x = np.asarray(torque_Nm, float).tolist()  # a Python loop over floats: ~10 ms per 10⁵ samples
    points, low, high, direction, extreme = [0], 0, 0, 0, 0
    for i in range(1, len(x)):
        if direction == 0:  # not yet moved by the threshold: the first travel decides
            low = i if x[i] < x[low] else low
            high = i if x[i] > x[high] else high
            if x[high] - x[low] > threshold_Nm:
                start, extreme, direction = (low, high, 1) if high > low else (high, low, -1)
                if start != 0:
                    points.append(start)
        elif direction * (x[i] - x[extreme]) > 0:
            extreme = i
        elif direction * (x[extreme] - x[i]) > threshold_Nm:
            points.append(extreme)
            extreme, direction = i, -direction
    if points[-1] != len(x) - 1:
        points.append(len(x) - 1)
    return points


def excursion_rate_Nm_per_s(time_s, torque_Nm) -> tuple[float, int] | None:
    """(median rate of the torque's excursions between reversals, in N·m per unit of the time
    stamps; their number), None with fewer than two. Each excursion's rate is read between its
    first crossings of 10 % and 90 % of its span, so holds at its ends do not slow it."""
    t, tau = np.asarray(time_s, float), np.asarray(torque_Nm, float)
    smooth = _running_median(tau, _SMOOTH_SAMPLES)
    lo, hi = np.percentile(smooth, [0.5, 99.5])
    if not hi > lo:
        return None
    threshold = REVERSAL_FRACTION * float(hi - lo)
    points = turning_points(smooth, threshold)
    rates = []
    for a, b in zip(points[:-1], points[1:]):
        span = smooth[b] - smooth[a]
        if abs(span) <= threshold:  # a partial first or last segment
            continue
        travelled = (smooth[a:b + 1] - smooth[a]) / span  # 0 → 1 along the excursion
        i10, i90 = a + int(np.argmax(travelled >= 0.1)), a + int(np.argmax(travelled >= 0.9))
        if t[i90] > t[i10]:
            rates.append(abs(smooth[i90] - smooth[i10]) / (t[i90] - t[i10]))
    if len(rates) < 2:
        return None
    return float(np.median(rates)), len(rates)


def _off(found: float, declared: float) -> bool:
    ratio = found / declared
    return not (1.0 / RATE_RATIO_LIMIT <= ratio <= RATE_RATIO_LIMIT)


def _how_far(found: float, declared: float) -> str:
    ratio = found / declared
    return f"{ratio:.4g}× faster than" if ratio > 1 else f"{1 / ratio:.4g}× slower than"


def _unit_hint(time_column: str, time_unit: str, other_column: str, other_unit: str) -> str:
    return (f"check the units of column {time_column!r} (read in {time_unit}; [runs.units] time = \"ms\" for "
            f"milliseconds, \"min\" for minutes) and column {other_column!r} (read in {other_unit}), or the "
            f"declared value")


def _rate_off(time_s, torque_Nm, declared_Nm_per_s: float | None) -> tuple[float, int] | None:
    """(rate, excursions) of the torque's excursions when more than :data:`RATE_RATIO_LIMIT`×
    off the declared loading rate; None when nothing is declared, read or off."""
    if declared_Nm_per_s is None or time_s is None:
        return None
    found = excursion_rate_Nm_per_s(time_s, torque_Nm)
    return found if found is not None and _off(found[0], declared_Nm_per_s) else None


def check_loading_rate(time_s, torque_Nm, declared_Nm_per_s: float | None, where: str, time_column: str,
                       time_unit: str, torque_column: str, torque_unit: str) -> None:
    """InputError when the torque's excursions ramp more than :data:`RATE_RATIO_LIMIT`× off the
    declared ``loading_rate_Nm_per_s`` in the run's time stamps (s)."""
    found = _rate_off(time_s, torque_Nm, declared_Nm_per_s)
    if found is None:
        return
    rate, count = found
    raise InputError(
        f"{where}: column {torque_column!r} ramps at {rate:.4g} N·m/s by column {time_column!r} (median of {count} "
        f"excursions between reversals), {_how_far(rate, declared_Nm_per_s)} the declared loading_rate_Nm_per_s = "
        f"{declared_Nm_per_s:g}; {_unit_hint(time_column, time_unit, torque_column, torque_unit)}")


def check_loading_rate_at_rate(sample_rate_Hz: float, torque_Nm, declared_Nm_per_s: float | None, where: str,
                               torque_column: str, torque_unit: str) -> None:
    """InputError when a hysteresis run without a time column, timed by ``[instrument]
    sample_rate_Hz``, ramps more than :data:`RATE_RATIO_LIMIT`× off the declared
    ``loading_rate_Nm_per_s``: the rate, the declared loading rate or the torque unit is wrong."""
    found = _rate_off(np.arange(len(torque_Nm)) / sample_rate_Hz, torque_Nm, declared_Nm_per_s)
    if found is None:
        return
    rate, count = found
    raise InputError(
        f"{where}: column {torque_column!r} ramps at {rate:.4g} N·m/s sampled at [instrument] sample_rate_Hz = "
        f"{sample_rate_Hz:g} (the run has no time column, so that rate times it; median of {count} excursions "
        f"between reversals), {_how_far(rate, declared_Nm_per_s)} the declared loading_rate_Nm_per_s = "
        f"{declared_Nm_per_s:g}; check the rate this run was sampled at (give the run a time column if it differs "
        f"from [instrument]'s), the unit of column {torque_column!r} (read in {torque_unit}), or the declared rate")


def check_te_speed(time_s, output_angle_rad, declared_rpm: float, where: str, time_column: str, time_unit: str,
                   angle_column: str, angle_unit: str, key: str) -> None:
    """InputError when the output angle turns more than :data:`RATE_RATIO_LIMIT`× off the
    declared output speed (rpm) in the run's time stamps (s)."""
    if time_s is None or not declared_rpm > 0:
        return
    rpm = _mean_rpm(time_s, output_angle_rad)
    if rpm is None or not _off(rpm, declared_rpm):
        return
    raise InputError(
        f"{where}: column {angle_column!r} turns at {rpm:.4g} rpm by column {time_column!r} (mean over the run), "
        f"{_how_far(rpm, declared_rpm)} the declared output speed {declared_rpm:g} rpm ({key}); "
        f"{_unit_hint(time_column, time_unit, angle_column, angle_unit)}")


def check_te_speed_at_rate(sample_rate_Hz: float, output_angle_rad, declared_rpm: float, where: str,
                           angle_column: str, angle_unit: str, key: str) -> None:
    """InputError when a TE run without a time column, timed by ``[instrument] sample_rate_Hz``,
    turns more than :data:`RATE_RATIO_LIMIT`× off the declared output speed: the model would
    time the run by that rate, so the rate, the speed or the angle unit is wrong."""
    if not declared_rpm > 0:
        return
    rpm = _mean_rpm(np.arange(len(output_angle_rad)) / sample_rate_Hz, output_angle_rad)
    if rpm is None or not _off(rpm, declared_rpm):
        return
    raise InputError(
        f"{where}: column {angle_column!r} turns at {rpm:.4g} rpm sampled at [instrument] sample_rate_Hz = "
        f"{sample_rate_Hz:g} (the run has no time column, so that rate times it), "
        f"{_how_far(rpm, declared_rpm)} the declared output speed {declared_rpm:g} rpm ({key}); check the rate "
        f"this run was sampled at (give the run a time column if it differs from [instrument]'s), the unit of "
        f"column {angle_column!r} (read in {angle_unit}), or the declared speed")


def _mean_rpm(time_s, output_angle_rad) -> float | None:
    """The output's mean speed over the run (rpm), None over no time."""
    t, phi = np.asarray(time_s, float), np.unwrap(np.asarray(output_angle_rad, float))
    span_s = float(t[-1] - t[0])
    if not span_s > 0:
        return None
    return abs(float(phi[-1] - phi[0])) / span_s * 60.0 / (2.0 * math.pi)
