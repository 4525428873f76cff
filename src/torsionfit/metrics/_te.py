"""Transmission-error (TE) metrics from measured data alone: the paper's K_d and K_t.

A TE run rotates the reducer at constant load; TE = θ_out − θ_in/R, output-referred. Under load
the TE carries the twist of the reducer on top of its kinematic error. Against a zero reference
(the TE of a no-load run in the same direction, or the encoders' zero) the paper defines

- K_d = T / TE(φ_k) at one output position, φ_k = 180° (paper Eqs. 13–14, Figs. 15, 17);
- K_t = T / mean_φ TE over whole output revolutions (Figs. 16, 18).
"""

import math

import numpy as np

from .._errors import InputError
from ..io._campaign import TransmissionErrorRun
from ..units import from_si
from ._hysteresis import _entry

TWO_PI = 2.0 * math.pi
#: width of the output-angle bins of a once-per-revolution TE profile (degrees)
PROFILE_BIN_DEG = 0.5


def _angles(run: TransmissionErrorRun) -> tuple[np.ndarray, np.ndarray]:
    """Unwrapped output angle and TE (rad), checked."""
    phi = np.asarray(run.output_angle_rad, dtype=float)
    te = np.asarray(run.te_rad, dtype=float)
    if not (phi.ndim == te.ndim == 1 and phi.size == te.size):
        raise InputError(
            f"TE run {run.name!r}: output angle and TE must be 1-D arrays of one length"
        )
    if phi.size < 8:
        raise InputError(f"TE run {run.name!r}: {phi.size} samples; expected a revolution of data")
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(te))):
        raise InputError(f"TE run {run.name!r}: non-finite output angle or TE values")
    # An angle logged modulo 360° jumps by a full turn; unwrapping is a no-op otherwise.
    return np.unwrap(phi), te


def _progress(run: TransmissionErrorRun, phi: np.ndarray) -> tuple[np.ndarray, int, float]:
    """Output rotation since the first sample (rad, ≥ 0 along the motion), the number of whole
    revolutions covered and the median angle step. A run sampled at N points per revolution
    covers a revolution with N samples (each sample stands for one step), hence ``+ step``."""
    progress = (phi - phi[0]) * (1.0 if phi[-1] >= phi[0] else -1.0)
    step = float(np.median(np.abs(np.diff(phi))))
    revolutions = int(math.floor((progress[-1] + step) / TWO_PI + 1e-9))
    if revolutions < 1:
        raise InputError(
            f"TE run {run.name!r}: covers {math.degrees(progress[-1]):.4g}° of output angle; "
            f"expected at least one full revolution (360°)"
        )
    return progress, revolutions, step


def te_profile(
    run: TransmissionErrorRun, bin_deg: float = PROFILE_BIN_DEG
) -> tuple[np.ndarray, np.ndarray]:
    """Once-per-revolution TE profile of a run: ``(angle, te)`` in rad, angle in [0, 2π).

    Samples are binned by output angle modulo 360° (``bin_deg`` wide bins); each non-empty bin
    gives its mean angle and mean TE, averaging the revolutions. Raises :class:`InputError`
    if the run is shorter than one revolution.
    """
    phi, te = _angles(run)
    _progress(run, phi)
    wrapped = np.mod(phi, TWO_PI)
    width = math.radians(bin_deg)
    index = np.minimum((wrapped // width).astype(np.int64), int(math.ceil(TWO_PI / width)) - 1)
    counts = np.bincount(index)
    used = counts > 0
    angle = np.bincount(index, weights=wrapped)[used] / counts[used]
    value = np.bincount(index, weights=te)[used] / counts[used]
    return angle, value


def te_metrics(
    run: TransmissionErrorRun,
    reference_run: TransmissionErrorRun | None = None,
    *,
    te_window_deg: float = 2.0,
) -> dict[str, dict]:
    """K_d, K_t and TE levels of one TE run, from the data alone.

    The zero reference ref(φ): the once-per-revolution TE profile of ``reference_run`` (a
    no-load run in the same direction), interpolated periodically at each sample's output
    angle; with no reference run, ref = 0 (the encoders' zero). Metrics (T = ``run.torque_Nm``):

    - ``te_180`` (arcmin): mean of TE − ref over samples whose output angle (mod 360°) lies
      within ±``te_window_deg`` of 180°, all revolutions;
    - ``te_mean`` (arcmin): mean of TE − ref over the whole revolutions of the run (trimmed to
      an integer number; samples weighted by the angle they cover, so speed ripple does not
      bias the mean);
    - ``kd`` = T / |te_180| and ``kt`` = T / |te_mean| (N·m/arcmin), also in N·m/° as
      ``kd_Nm_per_deg`` and ``kt_Nm_per_deg``; omitted for a no-load run (T = 0);
    - ``te_peak_to_peak`` (arcmin): peak-to-peak of the run's own TE profile (0.5° bins averaged
      over revolutions, mean removed), independent of the reference: the kinematic accuracy.

    Raises :class:`InputError` if the run (or its reference) is shorter than one revolution or
    no sample lies in the 180° window.
    """
    if not 0 < te_window_deg < 180:
        raise InputError(f"te_window_deg must be between 0 and 180, got {te_window_deg!r}")
    phi, te = _angles(run)
    progress, revolutions, step = _progress(run, phi)
    wrapped = np.mod(phi, TWO_PI)

    if reference_run is None or reference_run is run:
        ref = np.zeros_like(te)
        why = "a no-load run itself" if run.torque_Nm == 0 else "no no-load run in the same direction"
        ref_note = f"reference: the encoders' zero ({why})"
    else:
        ref_angle, ref_value = te_profile(reference_run)
        ref = np.interp(wrapped, ref_angle, ref_value, period=TWO_PI)
        ref_note = (
            f"reference: no-load run {reference_run.name!r} (its TE interpolated over output "
            f"angle mod 360°)"
        )
    twist = te - ref

    # TE at 180°: every sample within the window, over all revolutions.
    distance = np.abs(wrapped - math.pi)  # circular distance to 180°, as wrapped ∈ [0, 2π)
    window = distance <= math.radians(te_window_deg) + 1e-12
    if not np.any(window):
        raise InputError(
            f"TE run {run.name!r}: no sample within ±{te_window_deg:g}° of 180° output angle; "
            f"expected denser sampling or a wider te_window_deg"
        )
    te_180 = float(np.mean(twist[window]))

    # Revolution mean: whole revolutions only, midpoint-rule weights (the angle each covers).
    keep = progress < revolutions * TWO_PI - 0.5 * step
    p = progress[keep]
    weight = np.empty_like(p)
    if p.size > 1:
        weight[1:-1] = 0.5 * (p[2:] - p[:-2])
        weight[0], weight[-1] = p[1] - p[0], p[-1] - p[-2]
    else:
        weight[:] = 1.0
    weight = np.clip(weight, 0.0, None)
    if not weight.sum() > 0:
        weight[:] = 1.0
    te_mean = float(np.sum(weight * twist[keep]) / np.sum(weight))

    _, own_profile = te_profile(run)
    ptp = float(np.ptp(own_profile - own_profile.mean()))

    arcmin = lambda a: from_si(a, "angle", "arcmin")  # noqa: E731
    torque = float(run.torque_Nm)
    way = "forward" if run.direction >= 0 else "backward"
    condition = f"at {torque:.4g} N·m, {float(run.speed_rpm):.4g} rpm, {way}"
    n_window = int(np.count_nonzero(window))
    out = {
        "te_180": _entry(
            arcmin(te_180),
            "arcmin",
            f"mean TE − ref within ±{te_window_deg:g}° of 180° output angle ({n_window} samples, "
            f"all revolutions); {ref_note}",
        ),
        "te_mean": _entry(
            arcmin(te_mean),
            "arcmin",
            f"mean TE − ref over {revolutions} whole revolution(s); {ref_note}"
            + "".join(f"; {note}" for note in getattr(run, "notes", ())),
        ),
        "te_peak_to_peak": _entry(
            arcmin(ptp),
            "arcmin",
            f"peak-to-peak of the run's own TE profile ({PROFILE_BIN_DEG:g}° bins averaged over "
            f"revolutions, mean removed; no reference)",
        ),
    }
    if torque <= 0:
        return out  # a no-load run has no stiffness: it is the reference of the others
    for name, level, what in (("kd", te_180, "TE(180°)"), ("kt", te_mean, "revolution-mean TE")):
        if level == 0:
            raise InputError(
                f"TE run {run.name!r}: {what} equals the reference; {name} is undefined"
            )
        k = torque / abs(level)  # N·m/rad
        note = f"T / |{what} − ref| {condition}; {ref_note}"
        out[name] = _entry(from_si(k, "stiffness", "Nm/arcmin"), "Nm/arcmin", note)
        out[f"{name}_Nm_per_deg"] = _entry(
            from_si(k, "stiffness", "Nm/deg"), "Nm/deg", f"{name} in the paper's unit"
        )
    return out
