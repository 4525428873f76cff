"""Does the fitted model follow the data? A check no optimiser's "converged" replaces.

An optimiser stops at a stationary point, not necessarily a good one; and a likelihood with
AR(1) noise of coefficient near 1 scores mostly the residual's *increments*, so a fit whose loop
is twice as tall as the measured one can end "successful". The check: for every hysteresis run,
the MAP's residual RMSE against the RMSE of the straight line through the loop (angle = a + b·τ
by least squares on the same samples). Any hysteresis model worth its parameters beats that
line; one that does not is a local optimum or a model that cannot draw these data, and the fit
is reported not converged (never a decision).
"""

import numpy as np

from ..units import ANGLE_UNITS

ARCSEC = ANGLE_UNITS["arcsec"]


def straight_line_rmse(torque_Nm, angle_rad) -> float:
    """RMSE (rad) of the least-squares line angle = a + b·τ."""
    X = np.column_stack([np.ones(len(torque_Nm)), np.asarray(torque_Nm, float)])
    y = np.asarray(angle_rad, float)
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    return float(np.sqrt(np.mean((y - X @ coef) ** 2)))


def runs_not_followed(runs, residuals) -> list[dict]:
    """Hysteresis runs whose residuals (rad, one array per run, the run's samples in order) are
    larger than the straight line's: ``[{"run", "rmse_arcsec", "line_rmse_arcsec"}, …]``."""
    out = []
    for run, e in zip(runs, residuals):
        e = np.asarray(e, float)
        if run.kind != "hysteresis" or len(e) != len(run.angle_rad) or len(e) < 3:
            continue
        model, line = float(np.sqrt(np.mean(e**2))), straight_line_rmse(run.torque_Nm, run.angle_rad)
        if model > line:
            out.append({"run": run.name, "rmse_arcsec": model / ARCSEC, "line_rmse_arcsec": line / ARCSEC})
    return out


def not_followed_reason(bad: list[dict]) -> str:
    """One line for fit.json's ``reason`` and the summary."""
    worst = max(bad, key=lambda b: b["rmse_arcsec"] / b["line_rmse_arcsec"])
    return (f"the fitted model follows run {worst['run']!r} worse than a straight line through its loop "
            f"(RMSE {worst['rmse_arcsec']:.0f}″ against {worst['line_rmse_arcsec']:.0f}″"
            + (f"; {len(bad)} runs so" if len(bad) > 1 else "")
            + "): a local optimum or effects these data do not support — try more --starts or fewer effects")
