"""The earlier ramps' own twist as a predictor of a later ramp: what the loop's repeatability
allows any stationary model of a measured file.

A test programme runs the same large torque ramp several times. If the reducer repeated itself,
the twist of a later ramp at a given torque on a given branch would be the earlier ramps' twist
there, up to the noise. This reference predicts each sample of the held-out ramp by exactly
that: on the same monotone branch (same direction, same place in the ramp) of every earlier
large ramp, the twist interpolated at the sample's torque, averaged over those ramps. No model,
no parameters: its error is the ramp-to-ramp *walk* of the data (the loop drifting, widening or
narrowing from one cycle to the next) plus the noise of averaging a few ramps.

Any model whose prediction depends on the torque history alone (every model here, and the
Prandtl–Ishlinskii reference) can only beat it by averaging the noise better; where the walk
dominates, this RMSE is about what a stationary model can reach on the held-out ramp, and the
spread of the earlier ramps is all a predictive interval fitted to them can know of the walk.

- the torque axis is the running median of the measured torque (``pi_reference.filter_torque``),
  the branches are split at reversals of more than ``REVERSAL_FRACTION`` of the ramp's torque
  range (the motor-current torque's ripple does not split them);
- a held-out sample whose torque lies outside an earlier ramp's branch is predicted from the
  ramps that cover it, and left out (counted in ``covered``) if none does.

REAL measured data: JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0 (read from
``<repo>/../shared/data/cycloidal-jv``; nothing of it is stored in this repository).
"""

from __future__ import annotations

import numpy as np

from pi_reference import filter_torque

#: a reversal splits two branches once the torque has come back by this share of its range
REVERSAL_FRACTION = 0.1


def branches(torque) -> np.ndarray:
    """Index of the monotone branch of every sample (0, 1, …): a new branch starts after each
    turn of more than ``REVERSAL_FRACTION`` of the torque's range (the turn's extreme sample
    ends the branch before it)."""
    torque = np.asarray(torque, float)
    out = np.zeros(torque.size, dtype=int)
    if torque.size == 0:
        return out
    step = REVERSAL_FRACTION * float(np.ptp(torque))
    branch, direction = 0, 0
    extreme_at = 0  # the running extreme of the current branch, in its direction
    for n in range(1, torque.size):
        v = torque[n]
        if direction == 0:  # until the torque has moved by a step from the first, the direction is open
            if abs(v - torque[0]) > step:
                direction = 1 if v > torque[0] else -1
                seg = torque[:n + 1]
                extreme_at = int(np.argmax(seg) if direction == 1 else np.argmin(seg))
            continue
        if direction * (v - torque[extreme_at]) >= 0:
            extreme_at = n
        elif direction * (torque[extreme_at] - v) > step:
            branch += 1
            out[extreme_at + 1:] = branch
            direction = -direction
            seg = torque[extreme_at + 1:n + 1]
            extreme_at = extreme_at + 1 + int(np.argmax(seg) if direction == 1 else np.argmin(seg))
    return out


def _direction(torque, branch) -> dict[int, int]:
    """+1 for a branch whose torque rises, −1 for one that falls."""
    return {int(b): int(np.sign(torque[branch == b][-1] - torque[branch == b][0]) or 1)
            for b in np.unique(branch)}


def predict_ramp(torque, angle, earlier: list[np.ndarray], target: np.ndarray) -> np.ndarray:
    """Twist of the samples ``target`` (a boolean mask of one ramp) from the same branches of the
    ramps ``earlier`` (boolean masks), averaged; NaN where no earlier ramp covers the torque.

    ``torque`` is the filtered torque of the whole record; branch ``k`` of the target is matched
    with branch ``k`` of an earlier ramp when both run in the same direction, else with the
    earlier ramp's branch of that direction nearest in place (fraction of the ramp)."""
    torque = np.asarray(torque, float)
    angle = np.asarray(angle, float)
    t_tau = torque[target]
    t_branch = branches(t_tau)
    t_dir = _direction(t_tau, t_branch)
    n_t = t_branch.max() + 1
    sums = np.zeros(t_tau.size)
    counts = np.zeros(t_tau.size)
    for mask in earlier:
        e_tau, e_angle = torque[mask], angle[mask]
        e_branch = branches(e_tau)
        e_dir = _direction(e_tau, e_branch)
        n_e = e_branch.max() + 1
        for b in range(n_t):
            same = [k for k in range(n_e) if e_dir[k] == t_dir[b]]
            if not same:
                continue
            k = b if b in same else min(same, key=lambda k: abs(k / max(n_e - 1, 1) - b / max(n_t - 1, 1)))
            x, y = e_tau[e_branch == k], e_angle[e_branch == k]
            order = np.argsort(x, kind="stable")
            x, y = x[order], y[order]
            sel = t_branch == b
            inside = sel & (t_tau >= x[0]) & (t_tau <= x[-1])
            sums[inside] += np.interp(t_tau[inside], x, y)
            counts[inside] += 1
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / counts, np.nan)


def held_out_prediction(loop: dict, held_nr: int | None = None, large_from: int = 100) -> np.ndarray:
    """Prediction of every sample of the ramp ``held_nr`` (default: the last one) of a file read
    by ``pi_reference.read_loop``, from the earlier large ramps (``test_nr ≥ large_from``); NaN
    elsewhere and where no earlier ramp covers the torque."""
    nr = loop["test_nr"]
    held_nr = int(nr.max()) if held_nr is None else held_nr
    torque = filter_torque(loop["torque_Nm"])
    earlier = [nr == r for r in np.unique(nr) if large_from <= r < held_nr]
    if not earlier:
        raise ValueError(f"no large ramp (test_nr ≥ {large_from}) before ramp {held_nr}")
    target = nr == held_nr
    out = np.full(nr.size, np.nan)
    out[target] = predict_ramp(torque, loop["angle_rad"], earlier, target)
    return out
