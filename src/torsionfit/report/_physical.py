"""Are the fitted components physical? Checks of the posterior's physics no likelihood makes.

**A Dahl element that hooks.** Dahl friction ``(T_f + μ|τ|)·z`` turns at a reversal at the rate
``dz/dτ = 2/τ_d``: the friction torque changes by ``(2·level/τ_d + μ)`` times the applied torque's
change, and the mesh torque by ``1 − (2·level/τ_d + μ)`` of it. Above 1 the mesh torque — and the
twist — runs *against* the applied torque after every reversal: the twist moves back before the
loop turns, a hook no locked-input loop shows (sticking friction holds the mesh torque at most
still: slip elements, ``distributed_friction``, do exactly that). A fit ends there when a flat
span after each reversal is longer than one Dahl element can draw at its level: the friction's
shape and its level are traded, and their split is not the data's (measured loops: baseline
initial-pos1, base model, τ_d 2.2 N·m against T_f 2.9 N·m).

**A relay gap that reaches beyond its crossing.** The relays of a Preisach gap
(``gap_relays``) can draw any rate-independent hysteresis, not only a gap crossed in steps: with
a wide span their shares switch in the loaded flanks, where friction and compliance draw the
loop, or never switch at all (a constant whose size no sample reads). The fit then reads as
well and its gap is not the data's (measured split preload3-pos6, the relays and a
three-segment compliance fitted from the prior's starts: switches over −27…+35 N·m on ±40 N·m
loops and a geometric gap of 4.3° where the data's play reads 0.10°; the trail that added the
relays after a held gap ended at a gap of 36°).
"""

import numpy as np

from ..model import RELAY_FLANK_SHARE, DahlFriction, RelayGapBacklash, ThreeSegmentCompliance
from ._derived import first_segment_twist


def _dahl_terms(friction, params: dict, peak_load_Nm: float):
    """(level at the largest load T_f + μ·peak, μ, τ_d) of a Dahl element (N·m, 1, N·m); None
    for a friction model without one."""
    if not isinstance(friction, DahlFriction):
        return None
    mu = float(params.get("friction_load_coefficient", 0.0)) if friction.load_dependent else 0.0
    level = float(friction.sliding_level({**params, "friction_load_coefficient": mu}, peak_load_Nm))
    return level, mu, float(params["dahl_torque"])


def _ratio(level: float, mu: float, tau_d: float) -> float:
    return 2.0 * level / tau_d + mu


def _rise_Nm(level: float, tau_d: float) -> float:
    r = 2.0 * level / tau_d
    return tau_d * (r - 1.0 - np.log(r)) if r > 1.0 else 0.0


def dahl_hook_ratio(friction, params: dict, peak_load_Nm: float) -> float:
    """``2·(T_f + μ·peak)/τ_d + μ``: the friction torque's change per applied torque change just
    after a reversal at the largest load (above 1 the mesh torque runs backwards); NaN for a
    friction model without a Dahl element."""
    terms = _dahl_terms(friction, params, peak_load_Nm)
    return float("nan") if terms is None else _ratio(*terms)


def dahl_hook_rise_Nm(friction, params: dict, peak_load_Nm: float) -> float:
    """How far the mesh torque rises after a reversal before it turns (N·m): with
    ``r = 2·level/τ_d`` the rise ``−x + 2·level·(1 − e^(−x/τ_d))`` peaks at ``τ_d·(r − 1 − ln r)``
    (the level's own growth with the load left out); 0 when the element does not hook."""
    terms = _dahl_terms(friction, params, peak_load_Nm)
    return 0.0 if terms is None else _rise_Nm(terms[0], terms[2])


def dahl_hook_note(friction, params: dict, peak_load_Nm: float) -> str:
    """One line when the fitted Dahl element hooks (:func:`dahl_hook_ratio` > 1), else ""."""
    terms = _dahl_terms(friction, params, peak_load_Nm)
    if terms is None:
        return ""
    level, mu, tau_d = terms
    ratio = _ratio(level, mu, tau_d)
    if not np.isfinite(ratio) or ratio <= 1.0:
        return ""
    where = f" at {peak_load_Nm:.3g} N·m" if mu > 0 else ""
    return (f"the Dahl friction hooks: its saturation torque τ_d = {tau_d:.3g} N·m is below what "
            f"its level needs ({ratio:.2f} × the applied torque's change turns into friction just after a "
            f"reversal{where}), so after every reversal the model's mesh torque rises by up to "
            f"{_rise_Nm(level, tau_d):.3g} N·m and its twist runs back before the loop turns — "
            "friction doing work, which no locked-input loop shows; where the data do not hook, the fit traded the "
            "friction's shape for its level and their split from the other components is the model's, not the data's "
            "(distributed_friction: slip elements hold the mesh torque instead)")


#: a first compliance segment this many times softer than the second draws a steep crossing
#: about zero torque, as a gap does (catalog three-segment curves of harmonic drives: K2/K1
#: about 1.2–2; the virtual bench's: 1.4–2.1)
SOFT_SEGMENT_RATIO = 2.5
#: … and is named beside the gap when its lost motion is at least this share of the gap's
SOFT_SEGMENT_SHARE = 0.25


def soft_segment_lost_motion_rad(compliance, params: dict) -> float:
    """``2·T1·(1/K1 − 1/K2)``: the twist a three-segment compliance's first segment adds across
    zero torque beyond the second segment's line (rad); 0 for another compliance or a first
    segment no softer than the second."""
    if not isinstance(compliance, ThreeSegmentCompliance):
        return 0.0
    return float(first_segment_twist({k: float(params[k]) for k in ("k1", "k2", "t1")}))


def gap_segment_note(compliance, params: dict, sum_hdi_arcmin=None) -> str:
    """One line when the compliance's first segment is at least ``SOFT_SEGMENT_RATIO`` times
    softer than the second and its lost motion at least ``SOFT_SEGMENT_SHARE`` of the gap's,
    else "": the gap and that segment then share the crossing, and the gap alone is not the
    model's gap-like lost motion (SYNTHETIC independent bench at 12.5 Hz: a 60′ gap read as 15′
    of gap and a first segment 14× softer below 0.47 N·m adding 45′). ``sum_hdi_arcmin``: the 95 %
    HDI of their sum (the metric ``gap_with_first_segment``), quoted when given."""
    lost = soft_segment_lost_motion_rad(compliance, params)
    if lost <= 0.0:  # another compliance, or a first segment no softer than the second
        return ""
    k1, k2, t1 = (float(params[k]) for k in ("k1", "k2", "t1"))
    gap = float(params.get("gap", 0.0))
    if k2 / k1 < SOFT_SEGMENT_RATIO or lost < SOFT_SEGMENT_SHARE * gap:
        return ""
    arcmin = np.degrees(1.0) * 60.0
    interval = ("" if sum_hdi_arcmin is None else
                f" (95 % HDI {sum_hdi_arcmin[0]:.3g}–{sum_hdi_arcmin[1]:.3g}′, gap_with_first_segment)")
    return (f"the compliance's first segment is {k2 / k1:.3g}× softer than the second below T1 = {t1:.3g} N·m: it adds "
            f"{lost * arcmin:.3g}′ of twist across zero torque beside a gap of {gap * arcmin:.3g}′ — both draw the steep "
            f"crossing about zero torque, and on these data the model splits it between them; their sum, "
            f"{(gap + lost) * arcmin:.3g}′{interval}, is its gap-like lost motion, not geometric_gap alone (play, "
            "backlash and lost_motion read the whole loop)")


#: a relay gap is named when at least this share of it sits on relays switching further than
#: ``RELAY_FLANK_SHARE`` of the loops' peak torque from the relays' centre (in a loaded flank, not
#: in the gap's crossing) or on relays the loops never switch
RELAY_NOTE_SHARE = 0.1


def relay_gap_shares(backlash, params: dict, low_Nm: float, high_Nm: float) -> tuple[float, float]:
    """(share of the gap on relays switching further than ``RELAY_FLANK_SHARE`` of the larger of
    |low|, |high| from the centre, share on relays the applied torque range [low, high] never
    switches: up-switch above ``high`` or down-switch below ``low``) of a :class:`RelayGapBacklash`
    (the mesh torque's range is narrower by the friction, so the second is a share at least);
    (0, 0) for another gap. ``params``: the gap's own (``gap_centre_torque``, its span and
    ``gap_relay_logits``)."""
    if not isinstance(backlash, RelayGapBacklash):
        return 0.0, 0.0
    shares = np.asarray(backlash.shares(params), float)
    up, down = (np.asarray(x, float) for x in backlash.switches_Nm(params))
    centre = float(params["gap_centre_torque"])
    reach = RELAY_FLANK_SHARE * max(abs(low_Nm), abs(high_Nm))
    flank = (np.abs(up - centre) > reach) | (np.abs(down - centre) > reach)
    never = (up > high_Nm) | (down < low_Nm)
    return float(shares[flank].sum()), float(shares[never].sum())


def relay_gap_note(backlash, params: dict, low_Nm: float, high_Nm: float) -> str:
    """One line when at least ``RELAY_NOTE_SHARE`` of a relay gap switches in the loaded flanks
    or never (:func:`relay_gap_shares`), else ""."""
    flank, never = relay_gap_shares(backlash, params, low_Nm, high_Nm)
    if max(flank, never) < RELAY_NOTE_SHARE:
        return ""
    arcmin = np.degrees(1.0) * 60.0
    reach = RELAY_FLANK_SHARE * max(abs(low_Nm), abs(high_Nm))
    return (f"the relay gap reaches beyond its crossing: {100 * flank:.0f} % of its share sits on relays switching more "
            f"than {reach:.3g} N·m from their centre {float(params['gap_centre_torque']):+.3g} N·m (steps in the loaded "
            f"flanks, which friction and compliance draw) and {100 * never:.0f} % on relays these loops never switch "
            f"(applied torque {low_Nm:.3g} to {high_Nm:.3g} N·m: a constant whose size no sample reads); the relays draw "
            f"more than the gap's crossing, and geometric_gap ({float(params['gap']) * arcmin:.3g}′) is not the gap the "
            "data cross — play, backlash and lost_motion read the whole loop")
