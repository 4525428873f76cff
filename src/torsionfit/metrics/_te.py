"""Transmission-error (TE) metrics: the paper's K_d and K_t, one definition for data and model.

A TE run rotates the reducer at constant load T; TE = θ_out − θ_in/R, output-referred (paper
Eq. 13). Under load the TE carries the twist of the reducer on top of its kinematic error. The
paper's dynamic stiffness is K = T / TE (Eq. 14), read at one output position φ_k = 180° (K_d,
Eqs. 26–27, Figs. 15, 17) or with TE averaged over whole output revolutions (K_t, Eq. 28,
Figs. 16, 18). Here TE is taken against a zero reference ref(φ):

- the no-load TE of the same direction when the campaign has one (the once-per-revolution
  profile of that run): TE − ref is then the twist the load adds, the kinematic error removed;
- otherwise the encoders' zero (ref = 0), as the paper does: K_d then includes the kinematic
  error at 180°.

:func:`te_reading` is that definition on plain arrays. The data-only metrics (:func:`te_metrics`)
feed it a run's samples; the fitted model's ``kd_mean[RUN]``/``kt[RUN]`` feed it the model's
noise-free TE on an angle grid, so both read the same quantity. The kinematic part at 180°
(the zero-mean once-per-revolution variation of the reference, or of the run's own TE without
one) is reported beside them, and no-load runs get no stiffness (they are the reference).
"""

import math

import numpy as np

from .._errors import InputError
from ..io._campaign import TransmissionErrorRun
from ..units import from_si
from ._hysteresis import _entry, _who

TWO_PI = 2.0 * math.pi
#: width of the output-angle bins of a once-per-revolution TE profile (degrees)
PROFILE_BIN_DEG = 0.5
#: half-width (degrees) of the output-angle window around 180° that K_d averages over
TE_WINDOW_DEG = 2.0


def te_reading(torque_Nm, te_rad, reference_rad, in_window, weight, *, has_reference: bool):
    """K_d, K_t and TE levels of one loaded TE run from arrays at the same output angles.

    ``te_rad``: TE (lag-positive); ``reference_rad``: the no-load reference at those angles
    (zeros with ``has_reference=False``: the encoders' zero); ``in_window``: 1 where the output
    angle (mod 360°) lies within the 180° window, else 0; ``weight``: each point's share of whole
    output revolutions (0 outside them). Works on NumPy and JAX arrays alike (arithmetic and
    ``.sum()`` only), so the data and the model use this one function.

    Returns ``(te_180, te_mean, kinematic_180, kd, kt)``, SI (rad, N·m/rad): TE − ref averaged
    over the window and over whole revolutions (weighted), the kinematic part at 180° (window
    mean minus revolution mean of the reference — of the run's own TE without a reference —
    included in ``te_180`` only without a reference), K_d = |T| / |te_180|, K_t = |T| / |te_mean|.
    """
    window = in_window / in_window.sum()
    share = weight / weight.sum()
    twist = te_rad - reference_rad
    te_180 = (window * twist).sum()
    te_mean = (share * twist).sum()
    shape = reference_rad if has_reference else te_rad
    shape = shape - shape[0]  # a constant level cancels exactly, not to rounding
    kinematic_180 = (window * shape).sum() - (share * shape).sum()
    return te_180, te_mean, kinematic_180, abs(torque_Nm) / abs(te_180), abs(torque_Nm) / abs(te_mean)


def _angles(run: TransmissionErrorRun) -> tuple[np.ndarray, np.ndarray]:
    """Unwrapped output angle and TE (rad), checked."""
    phi = np.asarray(run.output_angle_rad, dtype=float)
    te = np.asarray(run.te_rad, dtype=float)
    if not (phi.ndim == te.ndim == 1 and phi.size == te.size):
        raise InputError(
            f"{_who(run)}: output angle and TE must be 1-D arrays of one length"
        )
    if phi.size < 8:
        raise InputError(f"{_who(run)}: {phi.size} samples; expected a revolution of data")
    if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(te))):
        raise InputError(f"{_who(run)}: non-finite output angle or TE values")
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
            f"{_who(run)}: covers {math.degrees(progress[-1]):.4g}° of output angle; "
            f"expected at least one full revolution (360°)"
        )
    return progress, revolutions, step


def _revolution_weights(progress: np.ndarray, revolutions: int, step: float) -> np.ndarray:
    """Midpoint-rule weights (the angle each sample covers) over the whole revolutions, 0 beyond
    them: speed ripple does not bias a revolution mean."""
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
    out = np.zeros_like(progress)
    out[keep] = weight
    return out


def in_te_window(wrapped_rad, te_window_deg: float = TE_WINDOW_DEG):
    """1.0 where an output angle in [0, 2π) lies within ±``te_window_deg`` of 180°, else 0.0."""
    return (abs(wrapped_rad - math.pi) <= math.radians(te_window_deg) + 1e-12) * 1.0


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
    te_window_deg: float = TE_WINDOW_DEG,
) -> dict[str, dict]:
    """K_d, K_t and TE levels of one TE run, from the data alone (:func:`te_reading`).

    The zero reference ref(φ): the once-per-revolution TE profile of ``reference_run`` (a
    no-load run in the same direction), interpolated periodically at each sample's output
    angle; with no reference run, ref = 0 (the encoders' zero). Metrics (T = ``run.torque_Nm``):

    - ``te_180`` (arcmin): mean of TE − ref over samples whose output angle (mod 360°) lies
      within ±``te_window_deg`` of 180°, all revolutions;
    - ``te_mean`` (arcmin): mean of TE − ref over the whole revolutions of the run (samples
      weighted by the angle they cover);
    - ``te_kinematic_180`` (arcmin): the kinematic part at 180° (the reference's — or without
      one the run's own — window mean minus revolution mean); removed from ``te_180`` by a
      reference, included in it without one;
    - ``kd`` = T / |te_180| and ``kt`` = T / |te_mean| (N·m/arcmin), also in N·m/° as
      ``kd_Nm_per_deg`` and ``kt_Nm_per_deg``; a no-load run (T = 0) has none: it is the
      reference of the others;
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
    torque = float(run.torque_Nm)

    has_reference = reference_run is not None and reference_run is not run and torque != 0
    if not has_reference:
        ref = np.zeros_like(te)
        why = "a no-load run itself" if torque == 0 else "no no-load run in the same direction"
        ref_note = f"reference: the encoders' zero ({why})"
    else:
        ref_angle, ref_value = te_profile(reference_run)
        ref = np.interp(wrapped, ref_angle, ref_value, period=TWO_PI)
        ref_note = (
            f"reference: no-load run {reference_run.name!r} (its TE interpolated over output "
            f"angle mod 360°)"
        )
        if reference_run.zero_group != run.zero_group:
            ref_note += (
                f"; the reference is in another zero group ({reference_run.zero_group!r}, this "
                f"run {run.zero_group!r}): the shift between the two zeros enters TE − ref (the "
                f"fitted model's kd_mean/kt take each group's zero out)"
            )

    window = in_te_window(wrapped, te_window_deg)
    if not np.any(window):
        raise InputError(
            f"{_who(run)}: no sample within ±{te_window_deg:g}° of 180° output angle; "
            f"expected denser sampling or a wider te_window_deg"
        )
    weight = _revolution_weights(progress, revolutions, step)
    with np.errstate(divide="ignore", invalid="ignore"):  # a zero level is reported below
        reading = te_reading(torque, te, ref, window, weight, has_reference=has_reference)
    te_180, te_mean, kinematic_180, kd, kt = (float(v) for v in reading)

    _, own_profile = te_profile(run)
    ptp = float(np.ptp(own_profile - own_profile.mean()))

    arcmin = lambda a: from_si(a, "angle", "arcmin")  # noqa: E731
    way = "forward" if run.direction >= 0 else "backward"
    condition = f"at {torque:.4g} N·m, {float(run.speed_rpm):.4g} rpm, {way}"
    n_window = int(np.count_nonzero(window))
    kinematic_where = "the reference's" if has_reference else "the run's own"
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
        "te_kinematic_180": _entry(
            arcmin(kinematic_180),
            "arcmin",
            f"kinematic part at 180°: {kinematic_where} TE within ±{te_window_deg:g}° of 180° minus "
            f"its revolution mean; "
            + ("removed from te_180 by the reference" if has_reference else "included in te_180"),
        ),
        "te_peak_to_peak": _entry(
            arcmin(ptp),
            "arcmin",
            f"peak-to-peak of the run's own TE profile ({PROFILE_BIN_DEG:g}° bins averaged over "
            f"revolutions, mean removed; no reference)",
        ),
    }
    if torque == 0:
        return out  # a no-load run has no stiffness: it is the reference of the others
    for name, level, k, what in (("kd", te_180, kd, "TE(180°)"), ("kt", te_mean, kt, "revolution-mean TE")):
        if level == 0:
            raise InputError(
                f"{_who(run)}: {what} equals the reference; {name} is undefined"
            )
        note = f"|T| / |{what} − ref| {condition}; {ref_note}"
        out[name] = _entry(from_si(k, "stiffness", "Nm/arcmin"), "Nm/arcmin", note)
        out[f"{name}_Nm_per_deg"] = _entry(
            from_si(k, "stiffness", "Nm/deg"), "Nm/deg", f"{name} in the paper's unit"
        )
    return out
