"""The gap crossings read off the data alone (metrics/_gap_crossing.py) and the prior of a gap
centred on a torque of its own that they centre. All loops here are SYNTHETIC."""

import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit.fit._prior import build_priors
from torsionfit.io import Campaign, HysteresisRun, Instrument, Reducer
from torsionfit.metrics import branch_crossing, gap_crossings
from torsionfit.model import HeldGapBacklash, Parameter

ARCSEC = np.pi / 180 / 3600


def _loop(centre_Nm, hold_Nm=1.0, friction_Nm=1.5, gap_rad=0.02, seed=0, peak_Nm=40.0):
    """A bench file's torque (play ramps of ±4 N·m, then large ramps of ±peak) and twist: a
    spring behind Coulomb friction (a play operator on the torque) and a held gap centred on
    ``centre_Nm``, the encoder's 19.8″ step and noise below it. The gap is crossed at applied
    torques centre ± (hold + friction)."""
    rng = np.random.default_rng(seed)
    turns = [0.0, 4, -4, 4, -4, peak_Nm, -peak_Nm, peak_Nm, -peak_Nm, peak_Nm, 0.0]
    tau = np.concatenate([np.linspace(a, b, int(abs(b - a) * 25), endpoint=False) for a, b in zip(turns[:-1], turns[1:])])
    tau = tau + 0.05 * rng.standard_normal(tau.size)
    mesh = np.empty_like(tau)
    p = 0.0
    for i, t in enumerate(tau):
        p = min(max(p, t - friction_Nm), t + friction_Nm)
        mesh[i] = p
    params = {"gap": gap_rad, "gap_torque": 0.1, "gap_hold_torque": hold_Nm, "gap_centre_torque": centre_Nm}
    gap = np.asarray(HeldGapBacklash(centred=False).run_twist(params, jnp.asarray(mesh), initial_state=-1.0))
    angle = mesh / 2000.0 + gap + 5 * ARCSEC * rng.standard_normal(tau.size)
    angle = np.round(angle / (19.8 * ARCSEC)) * 19.8 * ARCSEC
    return HysteresisRun("loop (SYNTHETIC)", np.arange(tau.size) * 0.01, tau, angle)


@pytest.mark.parametrize("seed, centre", [(1, -1.2), (2, 0.0), (3, 0.8)])
def test_the_crossings_are_read_where_the_gap_is_crossed(seed, centre):
    run = _loop(centre, seed=seed)
    found = gap_crossings([run])
    # the large branches that cross zero: −4 → +40 (from the play ramps' end), two +40 → −40,
    # two −40 → +40; the play ramps do not reach half the peak, the last 40 → 0 does not cross
    assert len(found.rising_Nm) == 3 and len(found.falling_Nm) == 2, found
    np.testing.assert_allclose(found.rising_Nm, centre + 2.5, atol=found.span_Nm)
    np.testing.assert_allclose(found.falling_Nm, centre - 2.5, atol=found.span_Nm)
    assert abs(found.centre_Nm - centre) < 0.5 * found.span_Nm
    assert abs(found.half_width_Nm - 2.5) < found.span_Nm


def test_a_loop_without_a_gap_has_no_crossing():
    run = _loop(0.0, gap_rad=0.0, seed=5)
    found = gap_crossings([run])
    assert found.rising_Nm == () and found.falling_Nm == ()
    assert np.isnan(found.centre_Nm) and np.isnan(found.half_width_Nm)
    # a branch too short to read three spans over
    assert np.isnan(branch_crossing([0.0, 0.5, 1.0], [0.0, 1.0, 2.0], 1, 1.0)[0])


def test_the_gap_centre_prior_sits_on_the_data_crossings():
    """gap_hold = {centred = false}: the prior of the band's centre is the data's crossing
    centre, to within the span each crossing is read over; without crossings it is the wide
    prior around zero."""
    param = [Parameter("gap_centre_torque", "real", "N·m", "centre")]
    reducer = Reducer("unit", rated_torque_Nm=40.0)
    campaign = Campaign(reducer, Instrument(), (_loop(0.8, seed=7),))
    mean, sd = build_priors(param, campaign)["gap_centre_torque"]
    assert abs(mean - 0.8) < 0.5 and sd == pytest.approx(0.025 * 40.0, rel=0.05)
    plain = Campaign(reducer, Instrument(), (_loop(0.8, gap_rad=0.0, seed=7),))
    assert build_priors(param, plain)["gap_centre_torque"] == (0.0, 0.05 * 40.0)


@pytest.mark.parametrize("seed, hold, friction", [(11, 1.0, 1.5), (12, 4.0, 1.0), (13, 0.5, 2.0)])
def test_the_hold_prior_sits_on_the_crossings_less_the_friction(seed, hold, friction):
    """gap_from_crossings: the crossings sit at ±(hold + friction); the hold torque's prior
    holds the truth within two sds and puts the crossings' half width (the most the hold can be)
    within 1.6 sds above its centre; the gap's crossing width on half the span the jump is read
    over."""
    params = [Parameter("gap_hold_torque", "positive", "N·m", "hold"), Parameter("gap_torque", "positive", "N·m", "w")]
    campaign = Campaign(Reducer("unit", rated_torque_Nm=40.0), Instrument(),
                        (_loop(0.0, hold_Nm=hold, friction_Nm=friction, seed=seed),))
    default = build_priors(params, campaign)
    priors = build_priors(params, campaign, gap_from_crossings=True)
    mean, sd = priors["gap_hold_torque"]
    assert abs(mean - np.log(hold)) < 2 * sd, (np.exp(mean), hold)
    assert 0 < np.log(hold + friction) - mean < 1.6 * sd
    assert default["gap_hold_torque"] == (np.log(0.1 * 40.0), 1.5)
    assert priors["gap_torque"][0] == pytest.approx(np.log(0.5 * 0.025 * 40.0), abs=0.05)
    # no crossing, no prior from it: the default's
    plain = Campaign(campaign.reducer, Instrument(), (_loop(0.0, gap_rad=0.0, seed=seed),))
    assert build_priors(params, plain, gap_from_crossings=True) == build_priors(params, plain)
