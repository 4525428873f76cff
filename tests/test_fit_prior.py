"""Priors from a first look at the data (fit/_prior.py)."""

import numpy as np
from test_fit_torque_error import _play_then_stiffness_ramps

from torsionfit.fit._prior import cycle_friction_Nm
from torsionfit.io import HysteresisRun
from torsionfit.metrics._hysteresis import grouped_cycles


def test_the_friction_read_off_a_loop_is_the_coulomb_level_at_every_amplitude():
    """cycle_friction_Nm (the data-only friction of the measured-metrics table and of the fit's
    prior): on a spring + gap + Coulomb-friction loop it reads the friction level F for the
    ±4 N·m cycles and the ±40 N·m ones alike — the amplitude dependence it shows on the
    preloaded measured units is the data's, not the reading's."""
    tau = _play_then_stiffness_ramps(seed=1)
    friction, k, gap, t_gap = 1.5, 600.0, 0.01, 0.3  # N·m, N·m/rad, rad, N·m
    state = np.zeros(tau.size)  # Coulomb friction as a play operator on the torque
    p = 0.0
    for i, t in enumerate(tau):
        p = min(max(p, t - friction), t + friction)
        state[i] = p
    angle = state / k + 0.5 * gap * np.tanh(state / t_gap)
    run = HysteresisRun("loop", np.arange(tau.size) * 0.01, tau, angle)
    (classes,) = grouped_cycles([run])
    for cycle in (classes.smallest, classes.largest):
        assert abs(cycle_friction_Nm(cycle) - friction) < 0.15, cycle_friction_Nm(cycle)


def test_the_gap_lag_prior_is_scaled_by_the_ramps_not_the_run():
    """The damped gap's time constant is centred on a tenth of the median ramp between torque
    reversals (sd two e-folds), not on the run's length: a measured file's fit took a lag forty
    ramps long (a gap that never finishes crossing) under a prior scaled by the whole run."""
    from torsionfit.fit._prior import build_priors, first_look_ramp_time_s
    from torsionfit.io import Campaign, Instrument, Reducer
    from torsionfit.model import Parameter

    tau = _play_then_stiffness_ramps(seed=2)
    time_s = np.arange(tau.size) * 0.01  # play ramps 0.59 s, stiffness ramps 5.49 s
    run = HysteresisRun("loop", time_s, tau, tau / 600.0)
    campaign = Campaign(Reducer("unit", rated_torque_Nm=20.0), Instrument(), (run,))
    ramp = first_look_ramp_time_s(campaign)
    assert 0.55 < ramp < 0.65, ramp  # ten play ramps against five stiffness ramps: the median is a play ramp
    mean_u, sd_u = build_priors([Parameter("gap_lag_time", "positive", "s", "lag")], campaign)["gap_lag_time"]
    assert np.isclose(np.exp(mean_u), 0.1 * ramp) and sd_u == 2.0
    assert (np.log(40 * ramp) - mean_u) / sd_u > 2.9  # a lag of forty ramps: three prior sds up
    assert first_look_ramp_time_s(Campaign(Reducer("te only", rated_torque_Nm=20.0), Instrument(), ())) is None
