"""Model quantities of the paper over posterior draws of a fit (``report.CampaignFit``):
the secant K_s of the paper's five-step loop at any loading rate, K_d at any load, speed and
direction, and the parts of the angle along a measured loop. Stiffness in N·m/arcmin."""

import equinox as eqx
import numpy as np

from .._x64 import in_float64
from ..io import Campaign, HysteresisRun
from ..plots import components_over_draws
from ..report import campaign_model, derived_metrics_for

#: a loading rate slow enough that the creep element is at rest (the paper's τ̇ → 0), per
#: second as a fraction of the rated torque (a step takes 10⁵ s, ≫ any creep time fitted here)
QUASI_STATIC_RATE_FRACTION = 1e-5


def _derived(fit, campaign: Campaign):
    return derived_metrics_for(campaign, campaign_model(campaign, fit.options), fit.options.lost_motion_pct)


@in_float64
def secant_draws(fit, loading_rates_Nm_per_s) -> np.ndarray:
    """(draws, rates) the paper's K_s = T_r / (θ(T_r, end of step 5) − θ_start) of the fitted
    model run through the five-step protocol from rest at each loading rate (N·m/arcmin)."""
    campaign = fit.campaign
    columns, first = [], None
    for rate in np.atleast_1d(np.asarray(loading_rates_Nm_per_s, float)):
        probe = HysteresisRun(name="protocol", time_s=np.zeros(2), torque_Nm=np.zeros(2), angle_rad=np.zeros(2),
                              loading_rate_Nm_per_s=float(rate))
        derived = _derived(fit, Campaign(reducer=campaign.reducer, instrument=campaign.instrument, runs=(probe,)))
        if first is None:
            first = derived
        else:  # only the protocol's times differ: keep the first's static fields, compiled once
            derived = eqx.tree_at(lambda d: d.protocol, first, derived.protocol)
        column = [s.name for s in derived.specs].index("stiffness_rated_from_start")
        columns.append(np.asarray(derived.over_draws(fit.metric_values))[:, column])
    return np.stack(columns, axis=1)


@in_float64
def quasi_static_rate(fit) -> float:
    """The loading rate (N·m/s) standing for τ̇ → 0: :data:`QUASI_STATIC_RATE_FRACTION` · T_r."""
    return QUASI_STATIC_RATE_FRACTION * fit.campaign.reducer.rated_torque_Nm


@in_float64
def kd_draws(fit, torque_Nm, speed_rpm, direction: int = 1) -> np.ndarray:
    """(draws, points) K_d = τ / TE(180°) of the fitted model at paired 1-D ``torque_Nm`` and
    ``speed_rpm`` (direction +1 forward, −1 backward), TE against the model's unloaded zero."""
    torque_Nm = np.atleast_1d(np.asarray(torque_Nm, float))
    speed_rpm = np.broadcast_to(np.asarray(speed_rpm, float), torque_Nm.shape)
    derived = _derived(fit, fit.campaign)
    return np.asarray(derived.kd_over_draws(fit.metric_values, torque_Nm, speed_rpm,
                                            np.full(torque_Nm.shape, float(direction))))


@in_float64
def run_component_draws(fit, n_draws: int, seed: int, max_points: int = 1500) -> dict:
    """Parts of the angle (rad) along every fitted run for ``n_draws`` posterior draws, by run
    name: ``{"elastic", "friction", "geometric", "creep", "kinematic", "offset", "total"}`` and,
    for a hysteresis run, ``"drive_torque"``, each (draws, points); ``"index"`` the run's
    samples shown (at most ``max_points``, evenly spread)."""
    idx_by_run = {}
    for i, run in enumerate(fit.campaign.runs):
        n = len(run)
        idx_by_run[i] = np.unique(np.linspace(0, n - 1, min(n, max_points)).astype(int))
    rng = np.random.default_rng(seed)
    u = fit.draws_u[rng.choice(len(fit.draws_u), size=min(n_draws, len(fit.draws_u)), replace=False)]
    comps = components_over_draws(fit.problem, u, idx_by_run)
    return {run.name: {**comps[i], "index": idx_by_run[i]} for i, run in enumerate(fit.campaign.runs)}
