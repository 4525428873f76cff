"""Does the fitted model follow the data? A check no optimiser's "converged" replaces.

An optimiser stops at a stationary point, not necessarily a good one; and a likelihood with
AR(1) noise of coefficient near 1 scores mostly the residual's *increments*, so a fit whose loop
is twice as tall as the measured one can end "successful". The check: for every hysteresis run,
the MAP's residual RMSE against the RMSE of the straight line through the loop (angle = a + b·τ
by least squares on the same samples). Any hysteresis model worth its parameters beats that
line; one that does not is a local optimum or a model that cannot draw these data, and the fit
is reported not converged (never a decision).

A sampled posterior is checked too, at its median: the density a sampler explores is not the
one the MAP's optimiser maximised (AR(1) coefficients, a likelihood tempered for misfit), and
its mass can lie away from the data while the MAP follows them — on the measured baseline pos6
loop, with the AR(1) coefficient free, the posterior median drew half the measured twist. The
posterior must beat the straight line as the MAP does, and stay within
:data:`POSTERIOR_RMSE_FACTOR` × the MAP's RMSE.
"""

import numpy as np

from ..units import ANGLE_UNITS

ARCSEC = ANGLE_UNITS["arcsec"]
#: a posterior whose median follows a run more than this many times worse than the MAP has left it
POSTERIOR_RMSE_FACTOR = 2.0


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


def runs_left_by_posterior(runs, median_residuals, map_residuals) -> list[dict]:
    """Hysteresis runs that the posterior's median follows worse than the straight line or than
    :data:`POSTERIOR_RMSE_FACTOR` × the MAP (residuals in rad, one array per run):
    ``[{"run", "rmse_arcsec", "line_rmse_arcsec", "map_rmse_arcsec"}, …]``."""
    out = []
    for run, e, e_map in zip(runs, median_residuals, map_residuals):
        e, e_map = np.asarray(e, float), np.asarray(e_map, float)
        if run.kind != "hysteresis" or len(e) != len(run.angle_rad) or len(e) < 3:
            continue
        rmse, rmse_map = float(np.sqrt(np.mean(e**2))), float(np.sqrt(np.mean(e_map**2)))
        line = straight_line_rmse(run.torque_Nm, run.angle_rad)
        if rmse > line or rmse > POSTERIOR_RMSE_FACTOR * rmse_map:
            out.append({"run": run.name, "rmse_arcsec": rmse / ARCSEC, "line_rmse_arcsec": line / ARCSEC,
                        "map_rmse_arcsec": rmse_map / ARCSEC})
    return out


def left_by_posterior_reason(bad: list[dict]) -> str:
    """One line for fit.json's ``reason`` and the summary."""
    worst = max(bad, key=lambda b: b["rmse_arcsec"] / b["map_rmse_arcsec"])
    return (f"the posterior has left the data: its median follows run {worst['run']!r} with RMSE "
            f"{worst['rmse_arcsec']:.0f}″ against the MAP's {worst['map_rmse_arcsec']:.0f}″ and a straight line's "
            f"{worst['line_rmse_arcsec']:.0f}″" + (f" ({len(bad)} runs so)" if len(bad) > 1 else "")
            + ": the sampled density's mass lies away from the fit — the model misses what these data show")
