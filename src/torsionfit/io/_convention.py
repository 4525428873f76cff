"""Do the data move the way the declared sign conventions say?

A hysteresis run's angle grows with its torque: positive torque twists the output forward
(``angle_sign`` = -1 declares a bench that counts the angle the other way, ``torque_sign`` = -1
one that counts the torque the other way). A reversed angle or torque reads cleanly and gives a
loop run the wrong way round, a negative play and negative slopes, so a run whose angle clearly
falls as the torque rises stops (:func:`check_twist_sign`). Which of the two columns is reversed
the data cannot tell (the loops differ only by their + and − sides swapped), so the message asks
for a declaration.

Loaded TE, below: does it move with the load the way the declared ``te_convention`` says?

In memory TE is lag-positive: the twist makes TE grow with the signed mesh torque
d·(|τ| + T_f), d = +1 forward, −1 backward. So, between two runs that share a TE zero,
(a) in one direction the revolution-mean TE moves away from zero with the load (up forward,
down backward), and (b) a forward run's mean TE lies above a backward run's. A bench whose
files are lag-negative, read as lag-positive, shows both the other way round.

The check uses run means over whole revolutions (the kinematic error averages out) and counts a
comparison only when its difference clears a noise margin; it stops only when clear
contradictions outnumber clear agreements, so noise and kinematic error never trigger it.
"""

import math
from pathlib import Path

import numpy as np

from .._errors import InputError
from ._campaign import TransmissionErrorRun
from ._plausibility import ARCMIN

#: a hysteresis run stops when the torque's share of its angle falls by more than this many
#: residual sds over the torque range (the 21 measured cycloidal loops reversed: 7.4–12.3)
SIGN_MARGIN = 2.0
#: a difference counts when it exceeds this many standard errors of the two means
MARGIN_SE = 4.0
#: samples over which TE noise is taken as correlated (for the standard error of a mean)
CORRELATION_SAMPLES = 20


def check_twist_sign(time_s, torque_Nm, angle_rad, where: str, angle_column: str, torque_column: str,
                     angle_sign: int = 1, torque_sign: int = 1) -> None:
    """InputError naming the file's columns when a hysteresis run's angle (after ``angle_sign``
    and ``torque_sign``)
    clearly falls as its torque rises: least squares of the angle on the torque, the time and a
    constant (a drift in time is not read as the load's), the torque's coefficient across the
    torque range (0.5–99.5 %) negative by more than :data:`SIGN_MARGIN` × the residual sd (the
    loop's width, noise and walk; at least 1 % of the angle's range), so a rigid unit's noise
    never stops a run."""
    tau, theta = np.asarray(torque_Nm, float), np.asarray(angle_rad, float)
    if tau.size < 20:
        return
    t = np.arange(tau.size, dtype=float) if time_s is None else np.asarray(time_s, float)  # untimed: in samples
    design = np.column_stack([tau, (t - t.mean()) / max(float(np.ptp(t)), 1e-12), np.ones_like(tau)])
    coef, *_ = np.linalg.lstsq(design, theta, rcond=None)
    lo, hi = np.percentile(tau, [0.5, 99.5])
    rise = float(coef[0]) * float(hi - lo)  # the twist the torque's range gives (rad)
    # exact data leave no residual: a rounding-sized coefficient is not a slope
    spread = max(float(np.std(theta - design @ coef)), 0.01 * float(np.ptp(theta)))
    if not rise < -SIGN_MARGIN * spread:
        return
    declared = [key for key, sign in (("angle_sign", angle_sign), ("torque_sign", torque_sign)) if sign == -1]
    if len(declared) == 1:
        fix = f"drop {declared[0]} = -1: the columns read as they are agree"
    elif declared:
        fix = "angle_sign = -1 and torque_sign = -1 cancel: declare the one the bench counts the other way"
    else:
        fix = ("declare angle_sign = -1 for this run if the bench counts the angle the other way, torque_sign = -1 "
               "if it counts the torque the other way (the data cannot tell which: the + and - sides swap)")
    raise InputError(
        f"{where}: column {angle_column!r} falls as column {torque_column!r} rises (by {-rise / ARCMIN:.4g} arcmin "
        f"over its {lo:.4g} to {hi:.4g} N·m, a drift in time apart); expected positive torque to twist the "
        f"output forward, to a larger angle; {fix}")


def _mean_and_se(run: TransmissionErrorRun) -> tuple[float, float]:
    """Mean TE over the run's whole revolutions (all of it if shorter) and its standard error."""
    phi = np.unwrap(np.asarray(run.output_angle_rad, float))
    te = np.asarray(run.te_rad, float)
    progress = np.abs(phi - phi[0])
    step = float(np.median(np.abs(np.diff(phi)))) if phi.size > 1 else 0.0
    turns = math.floor((progress[-1] + step) / (2 * math.pi) + 1e-9)
    keep = progress < turns * 2 * math.pi - 0.5 * step if turns >= 1 else np.ones(te.size, bool)
    kept = te[keep]
    noise = float(np.std(np.diff(te)) / math.sqrt(2.0)) if te.size > 2 else 0.0
    se = noise * math.sqrt(CORRELATION_SAMPLES / max(kept.size, 1))
    return float(np.mean(kept)), se


def check_te_convention(runs, where: str) -> None:
    """One-line InputError naming ``te_convention`` and the files when the loaded TE runs
    contradict their declared sign convention (see the module text)."""
    te_runs = [r for r in runs if isinstance(r, TransmissionErrorRun)]
    stats = {id(r): _mean_and_se(r) for r in te_runs}
    agree, against = 0, []
    for i, a in enumerate(te_runs):
        for b in te_runs[i + 1:]:
            if a.zero_group != b.zero_group:
                continue  # different zeros: their levels cannot be compared
            if a.direction == b.direction:
                if a.torque_Nm == b.torque_Nm:
                    continue
                low, high = (a, b) if a.torque_Nm < b.torque_Nm else (b, a)
                expected = high.direction * (stats[id(high)][0] - stats[id(low)][0])
                pair = (low, high)
            else:
                fw, bw = (a, b) if a.direction > 0 else (b, a)
                expected = stats[id(fw)][0] - stats[id(bw)][0]
                pair = (fw, bw)
            margin = MARGIN_SE * math.hypot(stats[id(a)][1], stats[id(b)][1])
            if expected > margin:
                agree += 1
            elif expected < -margin:
                against.append(pair)
    if against and len(against) > agree:
        first, second = against[0]
        files = sorted({Path(r.source).name or r.name for pair in against for r in pair})
        shown = ", ".join(files[:6]) + (f", ... ({len(files)} files)" if len(files) > 6 else "")
        conventions = sorted({r.te_convention for pair in against for r in pair})
        arcmin = 60 * 180 / math.pi
        raise InputError(
            f"{where}: TE moves against te_convention = {' / '.join(map(repr, conventions))} in "
            f"{len(against)} of {len(against) + agree} clear comparisons (e.g. {_label(first)} "
            f"mean TE {stats[id(first)][0] * arcmin:.4g} arcmin vs {_label(second)} "
            f"{stats[id(second)][0] * arcmin:.4g} arcmin) in {shown}; declare the bench's "
            f"te_convention ('lag_negative' if a load that makes the output lag gives negative TE) "
            f"in [instrument] or per run, and zero_group if it re-zeroes between tests"
        )


def _label(run: TransmissionErrorRun) -> str:
    way = "forward" if run.direction > 0 else "backward"
    return f"{run.name!r} ({way}, {run.torque_Nm:g} N·m)"
