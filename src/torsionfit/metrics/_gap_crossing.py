"""Where a hysteresis run crosses its gap, read off the data alone.

On a branch that loads through zero torque the twist of a reducer with play jumps where the
flanks leave one side of the gap for the other: over about one N·m of torque the twist moves
several times further than over any other N·m of the branch. The torque of that jump — on
rising branches and on falling ones — is where the gap is crossed. Measured loops cross at
torques that repeat from ramp to ramp and whose centre (the mean of the rising and the falling
crossing) lies off zero torque while the branches do not move with it; a fit reads the centre
off here as its first look at a gap of its own centre.
"""

from dataclasses import dataclass

import numpy as np

from .._segments import monotone_segments

#: a crossing's jump is read over this share of the run's peak torque (1 N·m of ±40 N·m)
JUMP_SPAN_SHARE = 0.025
#: a crossing jumps this many times the branch's median move over the same span
JUMP_RATIO = 2.0
#: a crossing branch starts no further than one jump span past zero torque (a ramp may start
#: near zero) and reaches past half the peak: the large cycles, whose crossing the fit weighs most
REACH_SHARE = 0.5


def branch_crossing(torque_Nm, angle_rad, direction: int, span_Nm: float,
                    jump_ratio: float = JUMP_RATIO) -> tuple[float, float]:
    """(torque in N·m, jump in rad) where the twist of one monotone branch (smoothed torque,
    ``direction`` ±1) moves furthest in the branch's direction over ``span_Nm`` of torque: the
    centre of that span and the move. (nan, nan) when the branch is shorter than three spans'
    reads or no move stands out (``jump_ratio`` × the branch's median move over the same span)."""
    t = np.asarray(torque_Nm, float)
    y = np.asarray(angle_rad, float)
    moves, centres = [], []
    for i in range(t.size):
        ahead = np.nonzero(direction * (t[i + 1:] - t[i]) >= span_Nm)[0]
        if ahead.size == 0:
            break
        j = i + 1 + ahead[0]
        moves.append(direction * (y[j] - y[i]))
        centres.append(0.5 * (t[i] + t[j]))
    if len(moves) < 3:
        return np.nan, np.nan
    k = int(np.argmax(moves))
    if moves[k] < jump_ratio * np.median(np.abs(moves)):
        return np.nan, np.nan  # no jump stands out: the branch does not cross a gap visibly
    return centres[k], moves[k]


@dataclass(frozen=True)
class GapCrossings:
    """The gap crossings of one or more hysteresis runs (N·m of applied torque)."""

    rising_Nm: tuple[float, ...]  # per branch loading from − to +, in time order
    falling_Nm: tuple[float, ...]  # per branch from + to −
    span_Nm: float  # the torque span each jump was read over

    @property
    def centre_Nm(self) -> float:
        """Mean of the rising and the falling crossing (medians over branches); nan unless both
        directions crossed."""
        if not (self.rising_Nm and self.falling_Nm):
            return float("nan")
        return float(0.5 * (np.median(self.rising_Nm) + np.median(self.falling_Nm)))

    @property
    def half_width_Nm(self) -> float:
        """Half the distance between the rising and the falling crossing (medians)."""
        if not (self.rising_Nm and self.falling_Nm):
            return float("nan")
        return float(0.5 * (np.median(self.rising_Nm) - np.median(self.falling_Nm)))


def gap_crossings(runs) -> GapCrossings:
    """The gap crossings of hysteresis runs (objects with ``torque_Nm`` and ``angle_rad``): on
    every monotone branch (10 % reversals of the smoothed torque) that starts within one jump
    span of zero torque or before it and reaches past half the run's peak, the
    :func:`branch_crossing` of the twist over 2.5 % of the peak torque."""
    rising, falling, spans = [], [], []
    for run in runs:
        tau = np.asarray(run.torque_Nm, float)
        angle = np.asarray(run.angle_rad, float)
        if tau.size < 10:
            continue
        smooth, segments = monotone_segments(tau)
        peak = float(np.max(np.abs(smooth)))
        span = JUMP_SPAN_SHARE * peak
        spans.append(span)
        for a, b, d in segments:
            if not (d * smooth[a] < span and d * smooth[b] > REACH_SHARE * peak):
                continue
            at, _ = branch_crossing(smooth[a:b + 1], angle[a:b + 1], d, span)
            if np.isfinite(at):
                (rising if d > 0 else falling).append(float(at))
    return GapCrossings(tuple(rising), tuple(falling), float(np.median(spans)) if spans else float("nan"))
