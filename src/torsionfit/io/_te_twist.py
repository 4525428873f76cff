"""Does the TE's load twist fit the reducer, and the campaign's loops?

Between a forward and a backward TE run at one load τ that share a TE zero, the revolution-mean
TE differs by the twist both ways: half the difference is h = (τ + T_f)/K + β/2 (lag-positive,
as in memory), so h / τ is the TE's reading of the reducer's compliance (friction and half the
lost motion over τ included). A TE column in another angle unit than declared scales it by the
unit's factor (60× arcmin/arcsec, 3600× deg/arcsec, 57.3× rad/deg) and reads cleanly; the TE
direction and convention checks do not see it. Two readings of it:

- against the campaign's hysteresis loops (their secant compliance, half the lost motion
  included, :func:`~torsionfit.io._plausibility.secant_compliance`): the two tests of one
  reducer differ by friction, lost motion over the load and the dynamic stiffness, a few times at
  most (:data:`TE_HYSTERESIS_LIMIT`). Runs whose output turns against their declared direction
  are left out (the direction check warns about them). Farther apart, the TE and the loops disagree; when the TE
  read in another angle unit agrees with the loops (within :data:`TE_UNIT_AGREEMENT`) and is
  plausible there, the run stops naming that unit; otherwise a warning names the keys to check;
- without loops (or with loops implausible themselves), the twist at the rated torque, h · T_r
  / τ, against the band of :func:`~torsionfit.io._plausibility.twist_band_arcmin`: a warning
  naming the units under which it is plausible.

Only pairs loaded to at least :data:`TE_LOAD_SHARE` of the rating (or, without one, of the
campaign's largest TE load) whose difference clears the noise count, and of those the most
loaded: nearer no load the friction and the gap make up most of h.
"""

import math

import numpy as np

from .. import units
from .._errors import InputError
from ._campaign import HysteresisRun, TransmissionErrorRun
from ._convention import MARGIN_SE, _mean_and_se
from ._plausibility import ARCMIN, secant_compliance, twist_band_arcmin, warn

#: pairs loaded below this share of the rated torque (or of the largest TE load) are not read
TE_LOAD_SHARE = 0.25
#: the TE's compliance and the loops' may differ by up to this factor either way (friction and
#: lost motion over the load, dynamic stiffness: about 2.3× at a quarter of the rating for a unit
#: with the measured printed loops' play of 2.5° and compliance of 0.084°/N·m); the smallest
#: angle-unit factor beyond it is rad/deg, 57.3×
TE_HYSTERESIS_LIMIT = 8.0
#: read in another unit, the TE's compliance agrees with the loops' within this factor
TE_UNIT_AGREEMENT = 3.0


def _turns_as_declared(run: TransmissionErrorRun) -> bool:
    """The output angle's net turning follows the run's ``direction`` (a run that does not has its
    own warning, and its mean TE is not that direction's)."""
    phi = np.unwrap(np.asarray(run.output_angle_rad, float))
    return bool(np.sign(phi[-1] - phi[0]) == np.sign(run.direction))


def _pairs(te_runs, stats, least_load_Nm: float):
    te_runs = [r for r in te_runs if _turns_as_declared(r)]
    for i, a in enumerate(te_runs):
        for b in te_runs[i + 1:]:
            if a.zero_group != b.zero_group or a.direction == b.direction or a.torque_Nm != b.torque_Nm:
                continue
            if not a.torque_Nm > 0 or a.torque_Nm < least_load_Nm:
                continue
            fw, bw = (a, b) if a.direction > 0 else (b, a)
            half = 0.5 * (stats[id(fw)][0] - stats[id(bw)][0])
            margin = 0.5 * MARGIN_SE * math.hypot(stats[id(fw)][1], stats[id(bw)][1])
            if half > margin:  # a difference the other way is the convention check's
                yield fw, bw, half / fw.torque_Nm


def check_te_twist(runs, rated_torque_Nm: float | None, where: str) -> None:
    """Check the TE runs' load twist against the loops and the reducer (see the module text):
    InputError when an angle unit explains a disagreement with the loops, warnings otherwise."""
    te_runs = [r for r in runs if isinstance(r, TransmissionErrorRun)]
    if len(te_runs) < 2:
        return
    stats = {id(r): _mean_and_se(r) for r in te_runs}
    scale = rated_torque_Nm if rated_torque_Nm is not None else max(r.torque_Nm for r in te_runs)
    read = list(_pairs(te_runs, stats, TE_LOAD_SHARE * scale))
    if not read:
        return
    # the most loaded pairs: the friction and half the lost motion weigh least in h / τ there
    top = max(fw.torque_Nm for fw, _, _ in read)
    read = [pair for pair in read if pair[0].torque_Nm == top]
    c_te = float(np.median([c for *_, c in read]))
    fw, bw = read[int(np.argsort([c for *_, c in read])[len(read) // 2])][:2]
    column = fw.te_column or "the TE"
    unit = fw.te_unit
    pair = (f"runs {fw.name!r} and {bw.name!r} (forward and backward at {fw.torque_Nm:g} N·m"
            f"{', and ' + str(len(read) - 1) + ' more pair(s)' if len(read) > 1 else ''})")
    low, high = twist_band_arcmin(scale)
    at = f"the rated torque {scale:g} N·m" if rated_torque_Nm is not None else f"the largest TE load {scale:g} N·m"
    loops = [c for c in (secant_compliance(r.torque_Nm, r.angle_rad) for r in runs if isinstance(r, HysteresisRun))
             if c is not None and c > 0]
    c_loops = float(np.median(loops)) if loops else None
    if c_loops is not None and not low <= c_loops * scale / ARCMIN <= high:
        c_loops = None  # implausible loops are no reference (their own warning names them)
    if c_loops is not None:
        ratio = c_te / c_loops
        if 1.0 / TE_HYSTERESIS_LIMIT <= ratio <= TE_HYSTERESIS_LIMIT:
            return
        fits = []
        if unit in units.ANGLE_UNITS:
            for other, factor in units.ANGLE_UNITS.items():
                f = factor / units.ANGLE_UNITS[unit]  # the TE's true size over its size as read
                if other != unit and 1.0 / TE_UNIT_AGREEMENT <= ratio * f <= TE_UNIT_AGREEMENT and \
                        low <= c_te * f * scale / ARCMIN <= high:
                    fits.append((abs(math.log(ratio * f)), other, f))
        said = (f"{where}: {column} ({unit}) of {pair} twists {c_te * scale / ARCMIN:.3g} arcmin at {at} (half the "
                f"forward-backward difference of the mean TE over the load), {ratio:.3g}× the hysteresis loops' "
                f"{c_loops * scale / ARCMIN:.3g} arcmin; the two tests of one reducer differ by a few times at most")
        if fits:
            fits.sort()
            best, f = fits[0][1], fits[0][2]
            how = (f"declare their unit (the columns' suffix, or output_angle = input_angle = \"{best}\" in "
                   f"[runs.units])" if column.startswith("columns") else
                   f"declare its unit (the column name's suffix, or te = \"{best}\" in [runs.units])")
            others = f" (or {' or '.join(other for _, other, _ in fits[1:])})" if len(fits) > 1 else ""
            raise InputError(f"{said}; read in {best}{others} the TE twists {c_te * f * scale / ARCMIN:.3g} arcmin, as "
                             f"the loops do: {how}")
        warn(f"{said} — check the TE's angle unit, the runs' torque_Nm and the loops' angle unit")
        return
    twist = c_te * scale / ARCMIN
    if low <= twist <= high:
        return
    fits = []
    if unit in units.ANGLE_UNITS:
        fits = [f"{twist * factor / units.ANGLE_UNITS[unit]:.3g} arcmin if it held {other}"
                for other, factor in units.ANGLE_UNITS.items()
                if other != unit and low <= twist * factor / units.ANGLE_UNITS[unit] <= high]
    hint = f" ({'; '.join(fits)})" if fits else ""
    warn(f"{where}: {column} ({unit}) of {pair} twists {twist:.3g} arcmin at {at} (half the forward-backward "
         f"difference of the mean TE over the load); a reducer twists {low:g}–{high:.3g} arcmin — is the TE's angle "
         f"unit right?{hint}")
