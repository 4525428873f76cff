"""Does a decision reach beyond what was measured? A ``kd`` requirement asks for K_d over a
torque × speed region; where that region leaves the loads and speeds of the campaign's TE runs,
the decision rests on the model's extrapolation, and the user is told which conditions."""

import numpy as np


class ExtrapolationWarning(UserWarning):
    """A decision covers operating conditions outside the measured ones (one line)."""


def measured_region(campaign) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """((lo, hi) load torque N·m, (lo, hi) output speed rpm) of the loaded TE runs, or None
    without any (no-load runs are the zero reference, not a measured load)."""
    loaded = [r for r in campaign.te_runs if r.torque_Nm > 0]
    if not loaded:
        return None
    torque = np.array([r.torque_Nm for r in loaded], float)
    speed = np.array([r.speed_rpm for r in loaded], float)
    return (float(torque.min()), float(torque.max())), (float(speed.min()), float(speed.max()))


def _outside(asked: tuple[float, float], measured: tuple[float, float], unit: str, what: str) -> str | None:
    # a relative tolerance: a region written as 380 for runs logged at 379.99 N·m is not an extrapolation
    tol = 1e-6 * max(abs(measured[1]), 1.0)
    if asked[0] >= measured[0] - tol and asked[1] <= measured[1] + tol:
        return None
    return f"{what} {asked[0]:g}–{asked[1]:g} {unit} asked, measured {measured[0]:g}–{measured[1]:g} {unit}"


def extrapolation(requirement, campaign) -> str | None:
    """One line saying which conditions of a ``kd`` requirement's region lie outside the
    measured TE loads and speeds, or None (not a ``kd`` requirement, or inside)."""
    if not requirement.is_kd:
        return None
    measured = measured_region(campaign)
    if measured is None:
        return None  # bind_requirements has refused a kd requirement without TE runs already
    parts = [p for p in (_outside(requirement.torque_range_Nm, measured[0], "N·m", "torque"),
                         _outside(requirement.speed_range_rpm, measured[1], "rpm", "speed")) if p]
    if not parts:
        return None
    return (f"{requirement.name!r}: the decision extrapolates the model beyond the measured conditions "
            f"({'; '.join(parts)})")
