"""Weakly informative priors, scaled from the rated torque and a first look at the data.

Every prior is normal in the unconstrained space: log-normal for positive quantities
(a median and a spread in e-folds), normal for real ones. Written as (mean_u, sd_u).
"""

import math

import numpy as np

from .._segments import fit_ramps
from ..io import Campaign, HysteresisRun
from ..metrics._gap_crossing import gap_crossings
from ..metrics._hysteresis import grouped_cycles


def first_look_stiffness(campaign: Campaign) -> float:
    """Rough elastic stiffness (N·m/rad) from the data: the slope of angle versus torque over
    the upper half of the torque range of the hysteresis runs, both signs, beyond the gap;
    from TE runs, load / mean TE when no hysteresis run exists."""
    slopes = []
    for run in campaign.runs:
        if isinstance(run, HysteresisRun):
            tau, th = run.torque_Nm, run.angle_rad
            top = np.max(np.abs(tau))
            for sign in (1, -1):
                sel = sign * tau > 0.5 * top
                if np.sum(sel) > 5 and np.ptp(tau[sel]) > 0:
                    slope = np.polyfit(tau[sel], th[sel], 1)[0]
                    if slope > 0:
                        slopes.append(slope)
    if slopes:
        return 1.0 / float(np.median(slopes))
    te = [abs(r.torque_Nm) / max(abs(np.mean(r.te_rad)), 1e-12) for r in campaign.te_runs if r.torque_Nm > 0]
    if te:
        return float(np.median(te))
    return campaign.reducer.rated_torque_Nm / math.radians(1.0)


def cycle_friction_Nm(cycle) -> float:
    """Half a cycle's width in torque at its mid angle (N·m): the torque where each branch
    passes the angle midway between the branches at zero torque. With a gap and a spring in
    series, friction is what shifts the branches apart in torque, so this reads the friction
    level off the data (``cycle``: a class of ``metrics._hysteresis.grouped_cycles``)."""
    j0 = int(np.argmin(np.abs(cycle.torque_Nm)))
    mid = 0.5 * (cycle.upper_rad[j0] + cycle.lower_rad[j0])
    # branches rise with torque
    at = [float(np.interp(mid, np.maximum.accumulate(b), cycle.torque_Nm)) for b in (cycle.upper_rad, cycle.lower_rad)]
    return 0.5 * (at[1] - at[0])


def first_look_loop(campaign: Campaign) -> tuple[float, float] | None:
    """(play in rad, friction torque in N·m) read off the hysteresis runs' cycles, or None.

    The play is the loop width at zero torque of the smallest cycles: the gap plus what
    friction holds open there, so the gap cannot be much wider. The friction level is half the
    largest cycles' width in *torque* at the loop's mid angle: with a gap and a spring in
    series, friction is what shifts the two branches apart in torque, so it cannot be much
    larger."""
    plays, widths = [], []
    for classes in grouped_cycles(campaign.hysteresis_runs):
        small = classes.smallest
        i0 = int(np.argmin(np.abs(small.torque_Nm)))
        plays.append(float(small.upper_rad[i0] - small.lower_rad[i0]))
        widths.append(2.0 * cycle_friction_Nm(classes.largest))
    if not plays or not all(np.isfinite(plays + widths)):
        return None
    play, width = float(np.median(plays)), float(np.median(widths))
    if play <= 0 or width <= 0:
        return None
    return play, 0.5 * width


def cycle_friction_readings_Nm(campaign: Campaign) -> tuple[float, float] | None:
    """(smallest, largest) cycles' :func:`cycle_friction_Nm`, medians over the hysteresis runs
    (N·m), or None when no run has cycles to read. On a file with play ramps and stiffness
    ramps the two differ by the friction the load adds and what a held gap shows."""
    readings = [(cycle_friction_Nm(c.smallest), cycle_friction_Nm(c.largest))
                for c in grouped_cycles(campaign.hysteresis_runs)]
    readings = [r for r in readings if all(math.isfinite(x) and x > 0 for x in r)]
    if not readings:
        return None
    small, large = np.median(np.array(readings), axis=0)
    return float(small), float(large)


def first_look_ramp_time_s(campaign: Campaign) -> float | None:
    """Median duration (s) of the hysteresis runs' monotone torque ramps (between reversals,
    as the fit splits them), or None without hysteresis runs."""
    durations = [float(r.time_s[b] - r.time_s[a]) for r in campaign.hysteresis_runs for a, b, _ in fit_ramps(r.torque_Nm)]
    durations = [d for d in durations if d > 0]
    return float(np.median(durations)) if durations else None


def build_priors(parameters, campaign: Campaign, gap_from_crossings: bool = False) -> dict[str, tuple[float, float]]:
    """(mean_u, sd_u) for each non-linear model parameter. Friction level and gap are centred
    on what the loops' cycles allow (:func:`first_look_loop`) when the campaign has them: a
    prior that lets friction exceed the loop's torque width, or the gap swallow the play, lets
    the two trade places on loops that are not exactly the model's. ``gap_from_crossings``:
    the held gap's hold torque and the gap's crossing width from the data's gap crossings
    (:func:`gap_crossing_priors`)."""
    rated = campaign.reducer.rated_torque_Nm
    k0 = first_look_stiffness(campaign)
    twist0 = rated / k0  # rated twist, rad
    durations = [float(np.ptp(r.time_s)) for r in campaign.hysteresis_runs] or [100.0]
    speeds = [r.speed_rpm * 2 * math.pi / 60 for r in campaign.te_runs] or [1.0]
    v_max = max(max(speeds), 1e-3)
    log = math.log
    table = {
        "stiffness": (log(k0), 1.5),
        "k1": (log(k0), 1.5), "k2": (log(k0), 1.5), "k3": (log(k0), 1.5),
        "t1": (log(0.25 * rated), 1.0), "t2_minus_t1": (log(0.5 * rated), 1.0),
        "elastic_rated_twist": (log(twist0), 1.5), "power_exponent": (0.0, 0.5),
        "compliance_asymmetry": (0.0, 0.3),
        "friction_torque": (log(0.02 * rated), 2.0),
        "dahl_torque": (log(0.02 * rated), 2.0),
        "breakaway_spread": (log(0.5), 1.0),  # log-sd of the elements' break-away levels
        "friction_load_coefficient": (log(0.1 / 0.9), 1.5),  # logit-normal around μ = 0.1
        # logit-normal around m = 0.5, wide: three sds down (a nested fit's start) is m ≈ 0.002,
        # the instantaneous load; m → 1 (a peak kept over the whole unloading) within 1.5 sd
        "friction_load_memory": (0.0, 2.0),
        "gap": (log(0.1 * twist0), 2.5),
        "gap_torque": (log(0.02 * rated), 2.0),
        "gap_closure": (log(0.9 / 0.1), 1.5),  # logit-normal around q = 0.9: mostly closed by friction
        "gap_preload_torque": (log(0.1 * rated), 1.5),
        "gap_hold_torque": (log(0.1 * rated), 1.5),
        "gap_relay_span": (log(0.1 * rated), 1.5),
        "gap_relay_span_share": (0.0, 1.5),  # logit-normal around half the bound, wide
        "gap_centre_torque": (0.0, 0.05 * rated),
        "gap_start": (0.0, 1.0),  # tanh-normal: g0 anywhere in (−1, 1)
        "gap_residual_share": (log(0.2 / 0.8), 1.5),  # logit-normal around w = 0.2: most of the gap preloaded
        "gap_residual_torque": (log(0.02 * rated), 2.0),
        "gap_step_logits": (0.0, 1.5),  # the steps' shares: even a priori, any one up to ~e^3 times another
        "gap_relay_logits": (0.0, 1.5),  # the relays' shares, as the steps'
        "series_share": (log(0.2 / 0.8), 1.5),  # logit-normal around φ = 0.2
        "preload_stiffening": (0.0, 1.5),  # logit-normal around s = 0.5: a second path as stiff as the first
        "preload_lift_torque": (log(0.1 * rated), 1.5),
        "creep_stiffness": (log(5 * k0), 2.0),
        "creep_time": (log(0.1 * max(durations)), 2.0),
        "viscous_friction": (log(0.01 * rated / v_max), 2.5),
        "speed_compliance_1": (0.0, 1.0 / v_max),
        "speed_compliance_2": (0.0, 1.0 / v_max**2),
        "torque_offset": (0.0, 0.05 * rated),
        "play_torque_offset": (0.0, 0.05 * rated),
        # per kelvin: a reducer's stiffness moves by well under 1 %/K; its no-load friction
        # (oil viscosity) by a few %/K
        "temperature_compliance": (0.0, 0.01),
        "temperature_friction": (0.0, 0.03),
        "friction_start": (0.0, 1.0),  # tanh-normal: z0 anywhere in (−1, 1)
    }
    if any(p.name == "gap_lag_time" for p in parameters):
        # a damped gap crossing ends well within a ramp (else the gap never finishes crossing
        # and the play would not show): centred on a tenth of the median ramp, not on the run's
        # length (under that prior a measured fit took a lag 40 ramps long: a gap that stays
        # put). Wide, so that three sds down — a nested fit's start — the lag is negligible: the
        # fit is free to take it to zero, the undamped gap. Read off the ramps only when asked for
        table["gap_lag_time"] = (log(0.1 * (first_look_ramp_time_s(campaign) or max(durations))), 2.0)
    if any(p.name == "friction_load_lag_time" for p in parameters):
        # as the gap's lag: a tenth of the median ramp, wide, its nested start (three sds down)
        # the instantaneous load
        table["friction_load_lag_time"] = (log(0.1 * (first_look_ramp_time_s(campaign) or max(durations))), 2.0)
    if any(p.name == "gap_centre_torque" for p in parameters):
        # a gap centred on a torque of its own: on the data's crossings when the loops show
        # them, to within the torque span each crossing is read over — the crossing is a thing
        # the data show directly. The large cycles': where the play ramps cross about another
        # centre (7 of 12 measured loops) no one centre places both (docs/validation.md)
        crossings = gap_crossings(campaign.hysteresis_runs)
        if math.isfinite(crossings.centre_Nm):
            table["gap_centre_torque"] = (crossings.centre_Nm, crossings.span_Nm)
        if any(p.name == "gap_relay_span" for p in parameters) and math.isfinite(crossings.half_width_Nm) \
                and crossings.half_width_Nm > 0:
            # a relay gap's switches spread about as far as the data's crossings lie apart
            # (friction shifts them further, hence the width)
            table["gap_relay_span"] = (log(crossings.half_width_Nm), 1.0)
    if gap_from_crossings:
        table.update(gap_crossing_priors(campaign))
    loop = first_look_loop(campaign) if any(p.name in ("gap", "friction_torque") for p in parameters) else None
    if loop is not None:
        play, friction = loop
        # a preloaded gap is not seen by the small cycles: their play does not bound it
        table["gap"] = (log(play), 2.5 if any(p.name == "gap_preload_torque" for p in parameters) else 1.0)
        table["friction_torque"] = (log(friction), 1.0)
    out = {}
    for p in parameters:
        if p.linear:
            continue
        if p.name not in table:
            raise KeyError(f"no prior for model parameter {p.name!r}")
        out[p.name] = table[p.name]
    return out




#: the hold torque's log-sd under :func:`gap_crossing_priors`: the crossings' half width, the
#: most the hold can be, 1.4 sd above its centre, twice it 2.8 sd
HOLD_LOG_SD = 0.5


def gap_crossing_priors(campaign: Campaign) -> dict[str, tuple[float, float]]:
    """Priors of the held gap's hold torque T_h and the gap's crossing width from where the
    large cycles' twist jumps (:func:`~torsionfit.metrics.gap_crossings`; empty when the data
    show no crossing both ways).

    The flanks cross the gap where the *mesh* torque reaches c ± T_h; friction in parallel
    carries part of the applied torque, so the data cross at c ± (T_h + friction), and T_h is at
    most the crossings' half width h. The data do not split h between the two (the play ramps'
    friction reading holds the hold as well where they cross the gap), so T_h is centred on h/2
    with log-sd :data:`HOLD_LOG_SD`: the hold cannot become a second friction element that
    releases far from where the data cross. The crossing is a jump over the torque span it is
    read over: the gap's tanh width is centred on half that span (log-sd 1), so the gap cannot
    spread into a compliance."""
    crossings = gap_crossings(campaign.hysteresis_runs)
    half_width, span = crossings.half_width_Nm, crossings.span_Nm
    if not (math.isfinite(half_width) and half_width > 0):
        return {}
    out = {"gap_hold_torque": (math.log(0.5 * half_width), HOLD_LOG_SD)}
    if math.isfinite(span) and span > 0:
        out["gap_torque"] = (math.log(0.5 * span), 1.0)
    return out
