"""Plausibility of a run's numbers for the reducer it claims to be.

A unit slip leaves a file perfectly readable: arcmin under an ``angle_deg`` header makes every
stiffness 60× too small, arcsec under it 3600×, with no error anywhere. These checks compare
what the data imply with what reducers are, and warn in one line (they never stop a run: an
unusual unit is possible, a silent 60× is not acceptable). Thresholds and their reasons:

- **Twist at rated torque** (secant, half the lost motion included), ``T_r / K``: precision
  cycloidal (RV) reducers twist 2–4 arcmin at rated torque, strain-wave (harmonic) 4–10,
  precision planetary 3–15, budget planetary up to ~40; plastic, 3D-printed and hobby gearing
  — which exists only at small ratings — 1–3°. Plausible: from ``TWIST_MIN_ARCMIN`` up to
  ``TWIST_MAX_ARCMIN``, lowered above ``SOFT_LIMIT_NM`` as √(SOFT_LIMIT_NM / T_r) (a 380 N·m
  unit may twist 2.3° at most, a 20 N·m one 10°). The band spans 2000×, less than 3600×: a
  3600× slip of any plausible value always lands outside it. A 60× slip does when it crosses
  an end: angles 60× too small for every unit twisting under 18 arcmin, 60× too large for a
  4.4 arcmin unit from ~100 N·m up (the encoder step check covers the rest when the angles
  are quantised).
  The hint names each unit, and with ``[reducer] ratio`` the input (motor) angle not yet
  divided by it, under which the twist would be plausible.
- **Encoder step**: angles that move in steps of a fixed size are quantised by the encoder; a
  step 20× coarser or finer than the declared ``encoder_resolution_arcsec`` is a unit slip
  (60×, 3600×, 57.3× for rad/deg) or a wrong resolution. A step more than 10 % finer than the
  declared resolution is a resolution declared too coarse (an encoder does not step finer than
  its resolution; a step coarser than it can be several counts at once): the fit's noise floor
  would sit above the data's.
- **Peak torque** above ``PEAK_TORQUE_LIMIT`` × the rated torque: no bench loads a reducer
  that far past its momentary rating (~2–5×); N·mm under a ``torque_Nm`` header gives 1000×.
- **TE direction**: a forward run's output angle increases sample by sample, a backward one's
  decreases (wrap-arounds ignored).
- **TE load** (an error): a TE run's torque column holds the load it declares in ``torque_Nm``
  (the load the model uses) within :data:`TE_LOAD_RATIO_LIMIT`× — N·mm read as N·m is 1000×.
- **TE ratio** (an error): a TE computed as output − input / ratio needs the two columns to turn
  at ``[reducer] ratio``; a tooth off, one column's unit or an input counting the other way
  makes the TE drift by degrees every revolution.

The TE's load twist against the loops and the reducer is a campaign's check
(:mod:`torsionfit.io._te_twist`).
"""

import math
import warnings

import numpy as np

from .. import units
from .._errors import InputError

ARCMIN = units.ANGLE_UNITS["arcmin"]
ARCSEC = units.ANGLE_UNITS["arcsec"]
#: stiffest plausible twist at rated torque (arcmin): stiffer than any catalog reducer by ~5×
TWIST_MIN_ARCMIN = 0.3
#: softest plausible twist at rated torque (arcmin) at and below SOFT_LIMIT_NM: 10°, 3× the
#: softest measured 3D-printed unit in the bundled examples
TWIST_MAX_ARCMIN = 600.0
#: rated torque (N·m) above which the softest plausible twist falls as √(SOFT_LIMIT_NM / T_r)
SOFT_LIMIT_NM = 20.0
#: an observed encoder step this many times off the declared resolution is warned about
STEP_RATIO_LIMIT = 20.0
#: an observed encoder step this much finer than the declared resolution is warned about (a
#: resolution declared as several steps: the measured loops' README gives 0.016°, three steps)
FINER_STEP_LIMIT = 1.1
#: a peak load this many times the rated torque is warned about
PEAK_TORQUE_LIMIT = 10.0
#: fraction of the extreme torque samples a loop's end points are read from
_END_FRACTION = 0.9


class PlausibilityWarning(UserWarning):
    """The data read cleanly but are implausible for the reducer (a unit slip, a sign, a
    direction). The message is one line naming the file and the column or key."""


def warn(message: str) -> None:
    """Issue a :class:`PlausibilityWarning` (whitespace collapsed to one line)."""
    warnings.warn(" ".join(message.split()), PlausibilityWarning, stacklevel=3)


def twist_band_arcmin(rated_torque_Nm: float) -> tuple[float, float]:
    """(lowest, highest) plausible twist at rated torque in arcmin for a reducer of that rating."""
    high = TWIST_MAX_ARCMIN * math.sqrt(min(1.0, SOFT_LIMIT_NM / rated_torque_Nm))
    return TWIST_MIN_ARCMIN, high


def secant_compliance(torque_Nm: np.ndarray, angle_rad: np.ndarray) -> float | None:
    """dθ/dτ (rad/N·m) between the loop's two ends: the median angle of the samples beyond
    90 % of the extreme torques on each side over the mean torque there. None without a load
    both ways (a one-sided run has no secant through zero)."""
    tau, theta = np.asarray(torque_Nm, float), np.asarray(angle_rad, float)
    lo, hi = np.percentile(tau, [0.5, 99.5])
    if not lo < 0 < hi:
        return None
    top, bottom = tau >= _END_FRACTION * hi, tau <= _END_FRACTION * lo
    d_tau = float(np.mean(tau[top]) - np.mean(tau[bottom]))
    return float(np.median(theta[top]) - np.median(theta[bottom])) / d_tau


def secant_twist(torque_Nm, angle_rad, rated_torque_Nm: float | None) -> tuple[float, float, float, float] | None:
    """(twist in arcmin at the rated torque — at the loop's own peak without a rating —, that
    torque in N·m, and the plausible band's low and high ends in arcmin); None without a rising
    secant (one-sided, or a reversed angle the sign check stops)."""
    c = secant_compliance(torque_Nm, angle_rad)
    if c is None or c <= 0:
        return None
    scale = rated_torque_Nm if rated_torque_Nm is not None else float(np.max(np.abs(torque_Nm)))
    return (c * scale / ARCMIN, scale, *twist_band_arcmin(scale))


def check_hysteresis(torque_Nm, angle_rad, rated_torque_Nm, where: str, angle_column: str,
                     angle_unit: str, torque_column: str, ratio: float | None = None) -> None:
    """Warn when the loop's twist at rated torque (or at its own peak, without a rating) or its
    peak load is implausible for the rating; with the reducer's ``ratio``, the hint names an
    input (motor) angle not divided by it."""
    reached = float(np.max(np.abs(torque_Nm)))
    if rated_torque_Nm is not None and reached > PEAK_TORQUE_LIMIT * rated_torque_Nm:
        warn(f"{where}: column {torque_column!r} reaches |torque| = {reached:.4g} N·m, "
             f"{reached / rated_torque_Nm:.3g}× the rated torque {rated_torque_Nm:.4g} N·m "
             f"(a bench stays below ~5×); is the torque unit right (N·mm read as N·m is 1000×)?")
    secant = secant_twist(torque_Nm, angle_rad, rated_torque_Nm)
    if secant is None:
        return  # a clearly reversed angle stopped the reader already (check_twist_sign)
    twist, scale, low, high = secant
    if rated_torque_Nm is not None:
        at, who = f"the rated torque {scale:.4g} N·m", "a reducer of that rating"
    else:  # no rating: the load the bench applied stands in for it
        at, who = f"its peak {scale:.4g} N·m (no rated_torque_Nm)", "a reducer loaded that far"
    if low <= twist <= high:
        return
    if angle_unit in units.ANGLE_UNITS:
        declared = units.ANGLE_UNITS[angle_unit]
        fits = [f"{twist * f / declared:.3g} arcmin if the column held {u}"
                for u, f in units.ANGLE_UNITS.items()
                if u != angle_unit and low <= twist * f / declared <= high]
    else:  # encoder counts: their size is the declared resolution, not a unit to slip
        fits = ["is [instrument] encoder_resolution_arcsec, the angle of one count, right?"]
    if ratio and ratio > 1 and low <= twist / ratio <= high:
        # the motor encoder's angle, not yet expressed at the output
        fits.append(f"{twist / ratio:.3g} arcmin if the column held the input angle, to be divided by "
                    f"[reducer] ratio = {ratio:g}")
    hint = f" ({'; '.join(fits)})" if fits else ""
    warn(f"{where}: column {angle_column!r} ({angle_unit}) twists {twist:.3g} arcmin at {at} "
         f"(secant stiffness {scale / twist:.3g} N·m/arcmin); {who} "
         f"twists {low:g}–{high:.3g} arcmin — is the angle unit right?{hint}")


def quantisation_step(values: np.ndarray) -> float | None:
    """The step a quantised signal moves in (its smallest non-zero change), None when the
    changes are not whole multiples of one step (unquantised, filtered or averaged data)."""
    d = np.abs(np.diff(np.asarray(values, float)))
    scale = float(np.max(d)) if d.size else 0.0
    d = d[d > 1e-9 * scale]
    if d.size < 20:
        return None
    q = float(np.min(d))
    k = d / q
    on_grid = np.abs(k - np.round(k)) < 0.02
    # most changes a few steps: a quantised slow signal; on_grid alone passes noise by chance
    if np.mean(on_grid) < 0.9 or np.median(k) > 1000:
        return None
    return q


def check_encoder_step(angle_rad, resolution_arcsec: float | None, where: str, column: str,
                       unit: str | None = None) -> None:
    """Warn when the angle moves in steps far from the declared encoder resolution (``unit``:
    the column's; a column in encoder counts has no unit to slip, only a resolution)."""
    if resolution_arcsec is None:
        return
    q = quantisation_step(angle_rad)
    if q is None:
        return
    ratio = q / ARCSEC / resolution_arcsec
    if 1.0 / STEP_RATIO_LIMIT <= ratio < 1.0 / FINER_STEP_LIMIT:
        # not a unit slip, but no encoder steps finer than its resolution: the fit's noise floor,
        # resolution/√12, would hold the noise above what the data show
        warn(f"{where}: column {column!r} moves in steps of {q / ARCSEC:.4g} arcsec, finer than the "
             f"[instrument] encoder_resolution_arcsec = {resolution_arcsec:g} (an encoder does not step finer "
             f"than its resolution); the fit's quantisation floor, resolution/√12, would be {1.0 / ratio:.3g}× the "
             f"data's: declare the step the angle moves in")
        return
    if 1.0 / STEP_RATIO_LIMIT <= ratio <= STEP_RATIO_LIMIT:
        return
    what = ("the resolution (the angle of one count) right" if unit is not None and unit not in units.ANGLE_UNITS
            else "the column's angle unit (or the resolution) right")
    warn(f"{where}: column {column!r} moves in steps of {q / ARCSEC:.4g} arcsec, {ratio:.4g}× "
         f"the [instrument] encoder_resolution_arcsec = {resolution_arcsec:g}; is {what}?")


#: how close the encoder step, read in another angle unit, must come to the declared resolution
#: for the step to say the column holds that unit (a unit factor is exact; 60× and 360× apart)
UNIT_STEP_TOLERANCE = 0.02


def check_angle_unit(torque_Nm, angle_rad, rated_torque_Nm: float | None, resolution_arcsec: float | None,
                     where: str, column: str, unit: str) -> None:
    """InputError when two readings of the data agree that the angle column holds another unit
    than declared: its encoder step, read in that unit, is the declared resolution (within
    :data:`UNIT_STEP_TOLERANCE`), and its twist at the rated torque (or at the loop's peak) is
    implausible as declared and plausible in that unit. One reading alone is a warning
    (:func:`check_hysteresis`, :func:`check_encoder_step`): a twist can be unusual, and a
    resolution mistyped."""
    if resolution_arcsec is None:
        return
    q = quantisation_step(angle_rad)
    secant = secant_twist(torque_Nm, angle_rad, rated_torque_Nm)
    if q is None or secant is None or unit not in units.ANGLE_UNITS:
        return  # in encoder counts the step is the resolution by construction
    twist, scale, low, high = secant
    if low <= twist <= high:
        return
    ratio = q / ARCSEC / resolution_arcsec
    declared = units.ANGLE_UNITS[unit]
    for other, factor in units.ANGLE_UNITS.items():
        f = factor / declared  # the angle's true size over its size as read, if the column held `other`
        if other == unit or abs(ratio * f - 1.0) > UNIT_STEP_TOLERANCE or not low <= twist * f <= high:
            continue
        at = f"the rated torque {scale:.4g} N·m" if rated_torque_Nm is not None else f"its peak {scale:.4g} N·m"
        raise InputError(
            f"{where}: column {column!r} read as {unit} moves in steps of {q / ARCSEC:.4g} arcsec, {ratio:.4g}× the "
            f"[instrument] encoder_resolution_arcsec = {resolution_arcsec:g}, and twists {twist:.3g} arcmin at {at}, "
            f"where a reducer twists {low:g}–{high:.3g} arcmin; both fit the column holding {other} (steps of "
            f"{q * f / ARCSEC:.4g} arcsec, a twist of {twist * f:.3g} arcmin): declare its unit {other} (the column "
            f"name's suffix, or angle = \"{other}\" in [runs.units])")


def check_torque_unit(torque_Nm, angle_rad, rated_torque_Nm: float | None, where: str, column: str,
                      unit: str) -> None:
    """InputError when the torque's peak and the loop's twist agree that the torque column holds
    a smaller unit than declared (N·mm read as N·m): the peak is beyond :data:`PEAK_TORQUE_LIMIT`
    × the rated torque and the twist at it implausible, and in that unit the peak lies within
    the bench's range (up to that limit) and the twist is plausible. One reading alone is a
    warning (:func:`check_hysteresis`)."""
    if rated_torque_Nm is None:
        return
    reached = float(np.max(np.abs(torque_Nm)))
    secant = None if reached <= PEAK_TORQUE_LIMIT * rated_torque_Nm else secant_twist(torque_Nm, angle_rad, rated_torque_Nm)
    if secant is None:
        return
    twist, _, low, high = secant
    if low <= twist <= high:
        return
    declared = units.TORQUE_UNITS[unit]
    for other, factor in units.TORQUE_UNITS.items():
        f = factor / declared  # the torque's true size over its size as read, if the column held `other`
        # read f times too small a torque, the compliance reads f times too small
        if f >= 1.0 or reached * f > PEAK_TORQUE_LIMIT * rated_torque_Nm or not low <= twist / f <= high:
            continue
        raise InputError(
            f"{where}: column {column!r} read as {unit} reaches |torque| = {reached:.4g} N·m, "
            f"{reached / rated_torque_Nm:.3g}× the rated torque {rated_torque_Nm:.4g} N·m, and the loop twists "
            f"{twist:.3g} arcmin at it, where a reducer twists {low:g}–{high:.3g} arcmin; both fit the column holding "
            f"{other} (a peak of {reached * f:.4g} N·m, a twist of {twist / f:.3g} arcmin): declare its unit {other} "
            f"(the column name's suffix, or torque = \"{other}\" in [runs.units]), or, if the column is right, "
            f"[reducer] rated_torque_Nm is {1 / f:g}× too small")


def check_te_direction(output_angle_rad, direction: int, where: str, column: str) -> None:
    """Warn when the output angle runs against the declared ``direction`` (+1 forward)."""
    d = np.diff(np.asarray(output_angle_rad, float))
    d = d[(d != 0) & (np.abs(d) < math.pi)]  # a wrap from 360° to 0° is no step back
    if d.size == 0:
        return
    against = float(np.mean(np.sign(d) != np.sign(direction)))
    if against > 0.5:
        declared, moving = ("forward", "decreases") if direction > 0 else ("backward", "increases")
        warn(f"{where}: column {column!r} {moving} over the run ({against:.0%} of its steps) but "
             f"direction = {declared!r}; check the direction key or the sign of the angle column")


#: a TE run's torque column whose median load is this many times off the declared torque_Nm
#: (either way) contradicts it: loads drift and ripple by per cents, a torque unit is 1000×
TE_LOAD_RATIO_LIMIT = 4.0


def check_te_torque(torque_series_Nm, declared_Nm: float, rated_torque_Nm: float | None, where: str,
                    column: str, unit: str, ratio: float | None = None) -> None:
    """InputError when a TE run's torque column reads another load than its declared
    ``torque_Nm`` (the load the model uses): the median |torque| more than
    :data:`TE_LOAD_RATIO_LIMIT`× off it, or, for a no-load run, beyond
    :data:`PEAK_TORQUE_LIMIT` × the rated torque. The message names the torque units under which
    the two agree, or, with the reducer's ``ratio``, a column holding the input (motor) torque."""
    if torque_series_Nm is None:
        return
    tau = np.asarray(torque_series_Nm, float)
    tau = tau[np.isfinite(tau)]
    if tau.size == 0:
        return
    # a brake's torque may be counted against the motion (negative on a backward run)
    load = abs(float(np.median(tau)))
    if declared_Nm > 0:
        agrees = lambda value: 1.0 / TE_LOAD_RATIO_LIMIT <= value / declared_Nm <= TE_LOAD_RATIO_LIMIT  # noqa: E731
    elif rated_torque_Nm is not None:  # no load: a drag torque, well below a bench's range
        agrees = lambda value: value <= PEAK_TORQUE_LIMIT * rated_torque_Nm  # noqa: E731
    else:
        return
    if agrees(load):
        return
    declared = units.TORQUE_UNITS[unit]
    fits = [f"{other} ({load * factor / declared:.4g} N·m)" for other, factor in units.TORQUE_UNITS.items()
            if other != unit and agrees(load * factor / declared)]
    hint = (f"the column holding {' or '.join(fits)} agrees with it: declare its unit (the column name's suffix, or "
            f"torque = \"{fits[0].split()[0]}\" in [runs.units]), or correct torque_Nm") if fits else \
        "check the column's unit and the declared torque_Nm"
    if not fits and ratio and ratio > 1 and declared_Nm > 0 and agrees(load * ratio):
        # a TE bench may log the motor's torque: the output's over the ratio (and the efficiency)
        hint = (f"it is the declared load over [reducer] ratio = {ratio:g} ({load * ratio:.4g} N·m at the output): if "
                f"the column holds the input (motor) torque, map the output torque as 'torque' or leave the column out")
    raise InputError(f"{where}: column {column!r} (read in {unit}) holds a load of {load:.4g} N·m (the median |torque| "
                     f"over the run), where the run declares torque_Nm = {declared_Nm:g}, the load the model uses; "
                     f"{hint}")


#: how far the input's turns per output turn may part from [reducer] ratio over a TE run: the
#: TE's own change moves the slope by at most ~0.5 % (a first-order kinematic error of 1° over
#: one revolution; a jump across a gap of a few degrees at the start less), a tooth of a ratio
#: under 100 is ≥ 1 %, an angle unit 57×–3600×
TE_RATIO_TOLERANCE = 0.01


def check_te_ratio(output_angle_rad, input_angle_rad, ratio: float, where: str, output_column: str,
                   input_column: str, output_unit: str, input_unit: str) -> None:
    """InputError when a TE run whose TE is output − input / ratio turns its input and output
    columns in another ratio than ``[reducer] ratio`` (the least-squares slope of the input's
    turning on the output's, more than :data:`TE_RATIO_TOLERANCE` apart): the TE would drift by
    the difference every revolution. Steps across an encoder's wrap-around are left out."""
    d_out, d_in = np.diff(np.asarray(output_angle_rad, float)), np.diff(np.asarray(input_angle_rad, float))
    if d_out.size < 2:
        return
    typical_out, typical_in = np.median(np.abs(d_out)), np.median(np.abs(d_in))
    # a wrap-around jumps by a turn, hundreds of times a sample's step
    keep = (np.abs(d_out) <= 100.0 * typical_out) & (np.abs(d_in) <= 100.0 * typical_in)
    turned_out = np.cumsum(np.where(keep, d_out, 0.0))
    if not abs(turned_out[-1]) > 0.5 * math.pi:
        return  # too little turning to read a ratio (the revolution check stops such a run)
    turned_in = np.cumsum(np.where(keep, d_in, 0.0))
    # a slope over the whole run: a periodic TE and a jump at the start tilt it less than the ends
    x = turned_out - turned_out.mean()
    found = float(np.dot(x, turned_in - turned_in.mean()) / np.dot(x, x))
    if abs(found / ratio - 1.0) <= TE_RATIO_TOLERANCE:
        return
    drift_arcmin = 2.0 * math.pi * abs(1.0 - found / ratio) / ARCMIN  # TE gained per output revolution
    if found < 0 < ratio and abs(-found / ratio - 1.0) <= TE_RATIO_TOLERANCE:
        hint = (f"the input turns against the output (a reducer that reverses direction, or an input encoder counting "
                f"the other way): give the run a te_<unit> column, or negate column {input_column!r}")
    else:
        # a column's true size over its size as read scales the ratio by f (input) or 1/f (output)
        fits = [f"column {column!r} holding {other}"
                for column, unit, power in ((input_column, input_unit, 1), (output_column, output_unit, -1))
                for other, factor in units.ANGLE_UNITS.items()
                if unit in units.ANGLE_UNITS and other != unit
                and abs(found * (factor / units.ANGLE_UNITS[unit]) ** power / ratio - 1.0) <= TE_RATIO_TOLERANCE]
        hint = (f"{' or '.join(fits)} would turn them at the ratio: declare its unit (the column name's suffix, or "
                f"[runs.units])" if fits else "check [reducer] ratio and the units of both columns (for counts, the "
                f"[instrument] encoder resolutions)")
    raise InputError(f"{where}: columns {input_column!r} ({input_unit}) and {output_column!r} ({output_unit}) turn "
                     f"{found:.5g}:1 over the run, where [reducer] ratio = {ratio:g}; te = output − input / ratio "
                     f"would drift {drift_arcmin:.4g} arcmin per output revolution; {hint}")
