"""Hysteresis-loop analysis from measured data alone (no model fit), DESIGN §1.4.

A hysteresis run is the paper's five-step protocol (input locked, output loaded):
0 → +T_r (virgin loading), +T_r → 0 → −T_r, −T_r → 0 → +T_r, possibly repeated. This module

1. splits the run into monotone torque segments at the turning points of a smoothed torque,
2. keeps the *loop branches* — segments that sweep (nearly) the whole range from the negative
   to the positive peak (the virgin loading from zero is not one),
3. resamples every branch as angle versus torque on one common torque grid and averages the
   branches of each direction (:func:`loop_branches`),
4. reads the catalog metrics off the averaged loop (:func:`hysteresis_metrics`).

Naming: the *upper* branch is the decreasing-torque one, the *lower* branch the
increasing-torque one. Friction makes the angle lag the load, so for τ > 0 twisting the
output forward the decreasing-torque branch lies above the increasing-torque one in angle.
"""

import math
from dataclasses import dataclass

import numpy as np

from .._errors import InputError
from ..io._campaign import HysteresisRun
from ..io._plausibility import quantisation_step
from .._segments import (
    default_window as _default_window,
    smooth_torque as _smooth_torque,
    split_monotone as _split_monotone,
)
from ..units import from_si

#: points of the common torque grid (the grid spacing is also the bin width)
DEFAULT_N_GRID = 201
#: a turning point needs the smoothed torque to retreat by this fraction of its range
DEFAULT_REVERSAL_FRACTION = 0.10
#: a branch must reach within this fraction of the range of both torque peaks
DEFAULT_FULL_RANGE_TOLERANCE = 0.10
#: the loop may fall short of ±T_r by this fraction of T_r; the metric is then extrapolated
RATED_TOLERANCE = 0.02
#: outermost fraction of the grid used for that linear extrapolation
_EXTRAPOLATION_SPAN = 0.05
#: a noise-made retreat must stay below this many standard deviations of the smoothed torque
_NOISE_SIGMAS = 8.0


# ----------------------------------------------------------------------------- results


def _entry(value: float, unit: str, note: str | None = None) -> dict:
    """One metric as plain JSON: ``{"value": float, "unit": str[, "note": str]}``."""
    entry = {"value": float(value), "unit": unit}
    if note:
        entry["note"] = note
    return entry


@dataclass(frozen=True, eq=False)
class LoopBranches:
    """A measured hysteresis loop resampled on a common torque grid (SI units).

    ``upper_rad`` is the mean of the decreasing-torque branches, ``lower_rad`` the mean of the
    increasing-torque branches; ``upper_all_rad`` / ``lower_all_rad`` hold every branch, one
    row each. ``segments`` lists every monotone torque segment of the run as
    ``(start, stop, direction)`` sample indices (``stop`` inclusive, direction ±1) and
    ``branch_segments`` the indices of those segments that are loop branches.
    """

    torque_Nm: np.ndarray
    upper_rad: np.ndarray
    lower_rad: np.ndarray
    upper_all_rad: np.ndarray
    lower_all_rad: np.ndarray
    peak_Nm: float
    trough_Nm: float
    smoothed_torque_Nm: np.ndarray
    segments: tuple[tuple[int, int, int], ...]
    branch_segments: tuple[int, ...]

    @property
    def midline_rad(self) -> np.ndarray:
        """Loop midline: mean of the upper and lower branch at each grid torque (rad)."""
        return 0.5 * (self.upper_rad + self.lower_rad)

    @property
    def width_rad(self) -> np.ndarray:
        """Loop width in angle, upper − lower, at each grid torque (rad)."""
        return self.upper_rad - self.lower_rad

    @property
    def n_upper(self) -> int:
        return int(self.upper_all_rad.shape[0])

    @property
    def n_lower(self) -> int:
        return int(self.lower_all_rad.shape[0])




def _binned_curve(
    tau: np.ndarray, theta: np.ndarray, grid: np.ndarray, spacing: float
) -> np.ndarray:
    """One branch's angle at the grid torques.

    Samples are binned by torque in bins one grid spacing wide centred on the grid; each bin
    gives the mean torque and the mean angle of its samples, and the grid values are linearly
    interpolated between these bin means. A mean rather than a median because bench angles
    are quantised: a median of quantised values is itself quantised, a mean dithers between
    levels. Pairing mean angle with mean torque (not with the bin centre) removes the bias of
    half-filled bins at the ends of the branch.
    """
    index = np.floor((tau - (grid[0] - 0.5 * spacing)) / spacing).astype(np.int64)
    index -= index.min()
    counts = np.bincount(index)
    used = counts > 0
    tau_mean = np.bincount(index, weights=tau)[used] / counts[used]
    theta_mean = np.bincount(index, weights=theta)[used] / counts[used]
    curve = np.interp(grid, tau_mean, theta_mean)
    # np.interp holds the end value constant; continue the end slope instead (at most half a
    # bin is involved, at the branch end that defines the common range).
    if tau_mean.size >= 2:
        lo = grid < tau_mean[0]
        hi = grid > tau_mean[-1]
        slope_lo = (theta_mean[1] - theta_mean[0]) / (tau_mean[1] - tau_mean[0])
        slope_hi = (theta_mean[-1] - theta_mean[-2]) / (tau_mean[-1] - tau_mean[-2])
        curve[lo] = theta_mean[0] + slope_lo * (grid[lo] - tau_mean[0])
        curve[hi] = theta_mean[-1] + slope_hi * (grid[hi] - tau_mean[-1])
    return curve


def _shared_range(smooth: np.ndarray, segments, ids) -> tuple[float, float]:
    """The torque range (N·m) all the segments ``ids`` of the smoothed torque cover."""
    lo = max(float(smooth[segments[k][0] : segments[k][1] + 1].min()) for k in ids)
    hi = min(float(smooth[segments[k][0] : segments[k][1] + 1].max()) for k in ids)
    return lo, hi


#: a dip of the smoothed torque below the torque its branch has reached counts when deeper than
#: this many σ of the noise left in it (shallower wiggles keep their own torque: holding them at
#: the running maximum would bias a noisy branch towards higher torques)
DIP_SIGMAS = 3.0


def reached_torque(smooth_segment: np.ndarray, direction: int, noise_Nm: float = 0.0) -> np.ndarray:
    """The torque a branch is read against at each of its samples (N·m): the torque it has
    reached — the running maximum of the smoothed torque on an increasing-torque branch, the
    running minimum on a decreasing one — where the torque has dipped back from it by more
    than :data:`DIP_SIGMAS` × ``noise_Nm`` (the noise left in the smoothed torque), else the
    torque itself.

    A torque estimated from motor current dips while the rotor crosses the gap (the current
    drops as it accelerates). Binned by the torque of the moment, the crossing's samples land
    back at lower torques — on REAL baseline initial-pos5 read at every 10th or 20th sample,
    inside the play ramps' zero-torque bin, which moved the play by 8–10 %. Where the torque
    rises monotonically (any synthetic ramp), it is the torque itself."""
    reached = np.maximum.accumulate(smooth_segment) if direction > 0 else np.minimum.accumulate(smooth_segment)
    return np.where(np.abs(reached - smooth_segment) > DIP_SIGMAS * noise_Nm, reached, smooth_segment)


def _branch_curves(smooth: np.ndarray, theta: np.ndarray, segments, ids, grid: np.ndarray,
                   noise_Nm: float = 0.0) -> np.ndarray:
    """Angle of each segment in ``ids`` binned on the torque ``grid`` against the torque it
    has reached (:func:`reached_torque`): one row per segment."""
    spacing = float(grid[1] - grid[0])
    return np.array([_binned_curve(reached_torque(smooth[s : e + 1], d, noise_Nm), theta[s : e + 1], grid, spacing)
                     for s, e, d in (segments[k] for k in ids)])


@dataclass(frozen=True)
class BranchWeights:
    """The mean of some branches on a torque grid as a fixed linear map of the angle record:
    ``θ̄_b`` = mean of ``angle[samples]`` over the samples with ``bins == b`` (``counts[b]`` of
    them); branch k at grid point g is ``(1 − w[k, g])·θ̄[lo[k, g]] + w[k, g]·θ̄[lo[k, g] + 1]``;
    the mean curve is the mean over the branches. What :func:`_branch_curves` computes, with
    everything that depends on the torque alone done once (the same torque, any angle: a
    model's prediction of the record, draw by draw)."""

    samples: np.ndarray
    bins: np.ndarray
    counts: np.ndarray
    lo: np.ndarray
    w: np.ndarray

    def curves(self, angle_rad: np.ndarray) -> np.ndarray:
        """Each branch on the grid (rows), NumPy."""
        sums = np.bincount(self.bins, weights=np.asarray(angle_rad)[self.samples], minlength=self.counts.size)
        mean = sums / self.counts
        return (1.0 - self.w) * mean[self.lo] + self.w * mean[self.lo + 1]


def branch_weights(smooth: np.ndarray, segments, ids, grid: np.ndarray, noise_Nm: float = 0.0) -> BranchWeights:
    """:class:`BranchWeights` of the segments ``ids`` of the smoothed torque ``smooth`` on
    ``grid`` (bins and interpolation as :func:`_binned_curve`: bin means of the reached torque
    and the angle, interpolated linearly between them, the end slopes continued past the ends)."""
    spacing = float(grid[1] - grid[0])
    samples, bins, counts, lo, w = [], [], [], [], []
    offset = 0
    for start, stop, direction in (segments[k] for k in ids):
        tau = reached_torque(smooth[start : stop + 1], direction, noise_Nm)
        index = np.floor((tau - (grid[0] - 0.5 * spacing)) / spacing).astype(np.int64)
        index -= index.min()
        count = np.bincount(index)
        used = np.flatnonzero(count > 0)
        if used.size < 2:
            raise InputError(f"a branch of {tau.size} samples spans fewer than two torque bins; expected a ramp")
        compact = np.full(count.size, -1)
        compact[used] = np.arange(used.size)
        tau_mean = np.bincount(index, weights=tau)[used] / count[used]
        j = np.clip(np.searchsorted(tau_mean, grid) - 1, 0, used.size - 2)
        samples.append(np.arange(start, stop + 1))
        bins.append(offset + compact[index])
        counts.append(count[used])
        lo.append(offset + j)
        w.append((grid - tau_mean[j]) / (tau_mean[j + 1] - tau_mean[j]))
        offset += used.size
    return BranchWeights(np.concatenate(samples), np.concatenate(bins), np.concatenate(counts).astype(float),
                         np.array(lo), np.array(w))


def _check_arrays(name: str, time_s, torque_Nm, angle_rad) -> tuple[np.ndarray, np.ndarray]:
    tau = np.asarray(torque_Nm, dtype=float)
    theta = np.asarray(angle_rad, dtype=float)
    time = np.asarray(time_s, dtype=float)
    if not (tau.ndim == theta.ndim == time.ndim == 1 and tau.size == theta.size == time.size):
        raise InputError(
            f"hysteresis run {name!r}: time, torque and angle must be 1-D arrays of one length"
        )
    if tau.size < 20:
        raise InputError(
            f"hysteresis run {name!r}: {tau.size} samples; a hysteresis loop needs at least 20"
        )
    if not (np.all(np.isfinite(tau)) and np.all(np.isfinite(theta)) and np.all(np.isfinite(time))):
        raise InputError(f"hysteresis run {name!r}: non-finite time, torque or angle values")
    # Equal time stamps are fine (benches quantise time): nothing below divides by Δt.
    if np.any(np.diff(time) < 0):
        raise InputError(f"hysteresis run {name!r}: time goes backwards; expected time order")
    return tau, theta


def _who(run) -> str:
    """The run and its file for messages: the file is what the user opens to fix it."""
    kind = "TE run" if run.kind == "transmission_error" else "hysteresis run"
    return f"{kind} {run.name!r}" + (f" (file {run.source})" if run.source else "")


def _check_run(run: HysteresisRun) -> tuple[np.ndarray, np.ndarray]:
    return _check_arrays(run.name, run.time_s, run.torque_Nm, run.angle_rad)


def loop_branches(
    run: HysteresisRun,
    *,
    n_grid: int = DEFAULT_N_GRID,
    smooth_samples: int | None = None,
    reversal_fraction: float = DEFAULT_REVERSAL_FRACTION,
    full_range_tolerance: float = DEFAULT_FULL_RANGE_TOLERANCE,
) -> LoopBranches:
    """Split a hysteresis run into loop branches and resample them on a common torque grid.

    - The torque is smoothed by sample index (running median of 5, then a quadratic
      Savitzky–Golay filter over ``smooth_samples``; default about 1/400 of the run, ≥ 5).
    - Turning points are extremes of the smoothed torque followed by a retreat larger than
      ``max(reversal_fraction × range, 8 σ)``, σ the noise left in the smoothed torque
      (estimated from the raw − smoothed residual), so noise cannot fake a reversal.
    - A segment between turning points is a loop branch when it reaches within
      ``full_range_tolerance × range`` of both the lowest and the highest smoothed torque;
      the virgin loading from zero and a final partial ramp are therefore not branches.
    - The grid spans the torque range common to all branches, ``n_grid`` points; every branch
      is binned on it by smoothed torque (bin means, see ``_binned_curve``).

    Raises :class:`InputError` when the run holds no full loop (an increasing and a decreasing
    branch through zero torque).
    """
    tau, theta = _check_run(run)
    if n_grid < 11:
        raise InputError(f"n_grid must be at least 11, got {n_grid}")
    width = _default_window(tau.size) if smooth_samples is None else int(smooth_samples)
    width = max(1, width | 1)  # odd

    smooth, sigma_smooth = _smooth_torque(tau, width)
    lo_peak, hi_peak = float(smooth.min()), float(smooth.max())
    span = hi_peak - lo_peak
    if span <= 0:
        raise InputError(f"{_who(run)}: the torque never changes; expected a loop")
    threshold = max(reversal_fraction * span, _NOISE_SIGMAS * sigma_smooth)
    segments = _split_monotone(smooth, threshold)

    reach = full_range_tolerance * span
    branch_ids = [
        k
        for k, (start, stop, _) in enumerate(segments)
        if smooth[start : stop + 1].min() <= lo_peak + reach
        and smooth[start : stop + 1].max() >= hi_peak - reach
    ]
    upper_ids = [k for k in branch_ids if segments[k][2] < 0]  # decreasing torque
    lower_ids = [k for k in branch_ids if segments[k][2] > 0]  # increasing torque
    # Both peaks must be clear of zero: a one-sided (pulsating) load is no full loop.
    if not upper_ids or not lower_ids or not lo_peak < -threshold < threshold < hi_peak:
        raise InputError(
            f"{_who(run)}: no full loop found ({len(lower_ids)} increasing and "
            f"{len(upper_ids)} decreasing torque ramps spanning {lo_peak:.4g}..{hi_peak:.4g} N·m); "
            f"expected at least one ramp each way between a negative and a positive peak"
        )

    # Common torque range of all branches (their smoothed extremes).
    g_lo, g_hi = _shared_range(smooth, segments, branch_ids)
    if not g_lo < 0 < g_hi:
        raise InputError(
            f"{_who(run)}: the loop branches share only "
            f"{g_lo:.4g}..{g_hi:.4g} N·m; expected a common range through zero torque"
        )
    grid = np.linspace(g_lo, g_hi, n_grid)

    def curves(ids: list[int]) -> np.ndarray:
        return _branch_curves(smooth, theta, segments, ids, grid, sigma_smooth)

    upper_all, lower_all = curves(upper_ids), curves(lower_ids)
    return LoopBranches(
        torque_Nm=grid,
        upper_rad=upper_all.mean(axis=0),
        lower_rad=lower_all.mean(axis=0),
        upper_all_rad=upper_all,
        lower_all_rad=lower_all,
        peak_Nm=hi_peak,
        trough_Nm=lo_peak,
        smoothed_torque_Nm=smooth,
        segments=tuple(segments),
        branch_segments=tuple(branch_ids),
    )


# ----------------------------------------------------------------------------- amplitude classes
#
# A bench file often holds ramps of several amplitudes in one run: small "play" ramps first,
# then large "stiffness" ramps. ``loop_branches`` keeps only the branches that sweep the whole
# range (the large cycles); the amplitude classes below keep every cycle and group them by size.

#: turning points for the amplitude classes: a retreat larger than this fraction of the run's
#: torque range (or 8 σ of the noise left in the smoothed torque), so small ramps are split too
#: (play ramps of amplitude a among stiffness ramps of ±L retreat by 2a, a/L of the range: seen
#: down to a = 2 % of L; the relative rule below does the real work against wiggles)
CYCLE_REVERSAL_FRACTION = 0.02
#: ... and a retreat larger than this fraction of the ramp it ends (its excursion from the
#: previous turning point): a controller's torque oscillation inside a ramp is no reversal.
#: The price: small ramps of amplitude a right after a ramp from a large peak L are seen only
#: when 2a > 0.25 (L + a), i.e. a > L/7; benches run their play ramps first.
CYCLE_RELATIVE_RETREAT = 0.25
#: a cycle branch crosses zero torque and its smaller peak |τ| is at least this fraction of its
#: larger one (a ramp from a small trough up to a large peak belongs to no amplitude class)
CYCLE_SYMMETRY = 0.5
#: branches whose amplitudes differ by less than this factor are one amplitude class
AMPLITUDE_CLASS_RATIO = 1.3


def _merge_wiggles(
    smooth: np.ndarray, segments: list[tuple[int, int, int]], threshold: float, relative: float
) -> list[tuple[int, int, int]]:
    """Monotone segments again, keeping only turning points whose retreat exceeds
    ``max(threshold, relative × excursion of the ramp they end)``: a zig-zag filter over the
    turning points of :func:`split_monotone`, with a threshold relative to each ramp's size."""
    points = [segments[0][0]] + [stop for _, stop, _ in segments]
    y = smooth[points]
    if len(points) < 3:
        return list(segments)
    turns = [0]
    cand = 1
    direction = 1 if y[1] > y[0] else -1
    for j in range(2, len(points)):
        if direction * (y[j] - y[cand]) > 0:
            cand = j  # the ramp goes on past its previous extreme
            continue
        ramp = abs(y[cand] - y[turns[-1]])
        if abs(y[cand] - y[j]) > max(threshold, relative * ramp):
            turns.append(cand)
            direction = -direction
            cand = j
    turns += [cand, len(points) - 1]
    bounds = sorted({points[t] for t in turns})
    return [
        (a, b, 1 if smooth[b] > smooth[a] else -1) for a, b in zip(bounds[:-1], bounds[1:]) if b > a
    ]


@dataclass(frozen=True, eq=False)
class AmplitudeClass:
    """The cycles of one amplitude, resampled on a common torque grid (SI units).

    ``amplitude_Nm`` is the median over its branches of min(|trough|, peak) of the smoothed
    torque; ``upper_rad`` the mean of its decreasing-torque branches, ``lower_rad`` the mean of
    its increasing-torque branches, on ``torque_Nm`` (the torque range all its branches share);
    ``upper_each_rad`` / ``lower_each_rad`` the branches one by one (rows in time order).
    ``segment_ids`` index :attr:`CycleClasses.segments`; ``centre_Nm`` is the torque midway
    between the median peak and the median trough of its branches (a ramp commanded about zero
    centres near zero; a torque zero offset moves it).
    """

    amplitude_Nm: float
    torque_Nm: np.ndarray
    upper_each_rad: np.ndarray
    lower_each_rad: np.ndarray
    segment_ids: tuple[int, ...]
    centre_Nm: float = 0.0

    @property
    def upper_rad(self) -> np.ndarray:
        """Mean decreasing-torque branch (rad)."""
        return self.upper_each_rad.mean(axis=0)

    @property
    def lower_rad(self) -> np.ndarray:
        """Mean increasing-torque branch (rad)."""
        return self.lower_each_rad.mean(axis=0)

    @property
    def n_upper(self) -> int:
        return int(self.upper_each_rad.shape[0])

    @property
    def n_lower(self) -> int:
        return int(self.lower_each_rad.shape[0])

    @property
    def width_rad(self) -> np.ndarray:
        """Loop width in angle, upper − lower, at each grid torque (rad)."""
        return self.upper_rad - self.lower_rad


@dataclass(frozen=True, eq=False)
class CycleClasses:
    """A run's cycles grouped by amplitude, ``classes`` sorted from smallest to largest.

    ``segments`` are all monotone segments of the smoothed torque, ``(start, stop, direction)``
    as in :class:`LoopBranches`; ``dropped`` says why amplitude groups were not kept (one
    direction only), ``dropped_amplitudes_Nm`` are those groups' amplitudes (N·m).
    """

    smoothed_torque_Nm: np.ndarray
    segments: tuple[tuple[int, int, int], ...]
    classes: tuple[AmplitudeClass, ...]
    dropped: tuple[str, ...] = ()
    dropped_amplitudes_Nm: tuple[float, ...] = ()
    #: σ of the noise left in the smoothed torque (N·m): the branches are read against the
    #: torque they have reached where it dips by more than :data:`DIP_SIGMAS` of it
    torque_noise_Nm: float = 0.0
    #: (trough, peak) in N·m of ramps that cross zero torque too far off centre to be cycle
    #: branches but repeat, up and down, between one trough and one peak: cycles about a
    #: torque other than zero (a torque zero offset), not a transition between amplitudes
    off_centre_ramps_Nm: tuple[tuple[float, float], ...] = ()

    @property
    def smallest(self) -> AmplitudeClass:
        """The smallest class that forms a loop (both directions)."""
        return self.classes[0]

    def no_play_reason(self, name: str = "run") -> str | None:
        """Why ``play`` cannot be read (one line), None when it can: ramps smaller than the
        smallest loop ran in one direction only — e.g. a single play ramp 0 → + → − → 0, whose
        one decreasing branch has no increasing branch to measure the width against: the play
        ramps form no loop, and the next cycles' width is not their play (friction at the larger
        load widens it); or smaller ramps cycle about a torque too far off zero to cross it as
        cycles (:attr:`off_centre_ramps_Nm`: a torque zero offset), the play being read at zero
        torque."""
        off = [(lo, hi) for lo, hi in self.off_centre_ramps_Nm if max(-lo, hi) < self.smallest.amplitude_Nm]
        if off:
            lo, hi = min(off, key=lambda r: r[1] - r[0])
            return (f"hysteresis run {name!r}: {_off_centre_text(lo, hi)}; the play is read at zero torque. The "
                    f"±{self.smallest.amplitude_Nm:.3g} N·m cycles' width is their backlash, not the play")
        smaller = [a for a in self.dropped_amplitudes_Nm if a < self.smallest.amplitude_Nm]
        if smaller:
            return (f"hysteresis run {name!r}: its smallest ramps (±{min(smaller):.3g} N·m) run in one direction "
                    f"only, no loop at zero torque to read the play from (a play ramp 0 → + → − → 0 alone has one "
                    f"full branch); expected at least two such ramps in a row. The ±{self.smallest.amplitude_Nm:.3g} "
                    f"N·m cycles' width is their backlash, not the play")
        return None

    def no_loading_reason(self, name: str = "run") -> str | None:
        """Why the loading slope cannot be read (one line), None when it can: ramps larger than
        the largest loop ran in one direction only (a single stiffness ramp 0 → + → − → 0): the
        smaller cycles' slope is not the stiffness ramps' (on a real reducer the gap and friction
        weigh more there)."""
        larger = [a for a in self.dropped_amplitudes_Nm if a > self.largest.amplitude_Nm]
        if larger:
            return (f"hysteresis run {name!r}: its largest ramps (±{max(larger):.3g} N·m) run in one direction "
                    f"only, no loop to read the loading slope from (a ramp 0 → + → − → 0 alone has one full "
                    f"branch); expected at least two such ramps in a row. The ±{self.largest.amplitude_Nm:.3g} "
                    f"N·m cycles are not the stiffness ramps")
        return None

    def play_class(self, name: str = "run") -> AmplitudeClass:
        """The class ``play`` is read from, the smallest cycles; :class:`InputError` with
        :meth:`no_play_reason` when there is none."""
        if (why := self.no_play_reason(name)) is not None:
            raise InputError(why)
        return self.smallest

    def loading_class(self, name: str = "run") -> AmplitudeClass:
        """The class the loading slope is read from, the largest cycles; :class:`InputError`
        with :meth:`no_loading_reason` when there is none."""
        if (why := self.no_loading_reason(name)) is not None:
            raise InputError(why)
        return self.largest

    @property
    def largest(self) -> AmplitudeClass:
        return self.classes[-1]


def cycle_classes(
    time_s,
    torque_Nm,
    angle_rad,
    *,
    name: str = "run",
    n_grid: int = DEFAULT_N_GRID,
    smooth_samples: int | None = None,
) -> CycleClasses:
    """Split a hysteresis record into monotone torque ramps and group its cycles by amplitude.

    Array level (no Campaign objects): ``time_s`` (s, non-decreasing, repeated stamps are fine),
    ``torque_Nm`` (N·m) and ``angle_rad`` (rad), 1-D of one length; ``name`` only names the
    record in messages.

    - The torque is smoothed as in :func:`loop_branches` (running median of 5, quadratic
      Savitzky–Golay over ``smooth_samples``, default about 1/400 of the record) and split at
      its turning points, a turning point needing a retreat larger than
      ``max(CYCLE_REVERSAL_FRACTION × range, 8 σ)`` (so that small ramps are split as well)
      and larger than ``CYCLE_RELATIVE_RETREAT`` × the ramp it ends (so that a controller's
      torque oscillation inside a ramp is not taken for a reversal).
    - A *cycle branch* is a segment that crosses zero torque with min(|trough|, peak) at least
      ``CYCLE_SYMMETRY`` × max(|trough|, peak); its amplitude is min(|trough|, peak). A virgin
      loading from zero, a final partial ramp or a ramp from a small trough to a large peak is
      no cycle branch.
    - Branches are sorted by amplitude and split into classes wherever the next amplitude is
      more than ``AMPLITUDE_CLASS_RATIO`` times the previous one. A class needs an increasing
      and a decreasing branch; its branches are binned on ``n_grid`` torques over the range they
      all share (bin means by smoothed torque, as in :func:`loop_branches`) and averaged by
      direction.

    Raises :class:`InputError` when the record holds no class with both directions.
    """
    tau, theta = _check_arrays(name, time_s, torque_Nm, angle_rad)
    if n_grid < 11:
        raise InputError(f"n_grid must be at least 11, got {n_grid}")
    width = _default_window(tau.size) if smooth_samples is None else int(smooth_samples)
    width = max(1, width | 1)
    smooth, sigma = _smooth_torque(tau, width)
    span = float(np.ptp(smooth))
    if span <= 0:
        raise InputError(f"hysteresis run {name!r}: the torque never changes; expected a loop")
    # Split at every reversal above the noise, then keep the turning points that pass both
    # thresholds (the zig-zag over them judges the first extreme by its retreat alone).
    noise = max(_NOISE_SIGMAS * sigma, 1e-12 * span)
    threshold = max(CYCLE_REVERSAL_FRACTION * span, noise)
    segments = _merge_wiggles(
        smooth, _split_monotone(smooth, noise), threshold, CYCLE_RELATIVE_RETREAT
    )

    amplitude, extent, lopsided = {}, {}, []
    for k, (start, stop, direction) in enumerate(segments):
        lo, hi = float(smooth[start : stop + 1].min()), float(smooth[start : stop + 1].max())
        extent[k] = (lo, hi)
        if lo < 0 < hi and min(-lo, hi) >= CYCLE_SYMMETRY * max(-lo, hi):
            amplitude[k] = min(-lo, hi)
        elif lo < 0 < hi:
            lopsided.append((lo, hi, direction))
    groups: list[list[int]] = []
    for k in sorted(amplitude, key=amplitude.get):
        if groups and amplitude[k] <= AMPLITUDE_CLASS_RATIO * amplitude[groups[-1][-1]]:
            groups[-1].append(k)
        else:
            groups.append([k])

    classes, dropped, dropped_amplitudes = [], [], []
    for ids in groups:
        ids = sorted(ids)
        amp = float(np.median([amplitude[k] for k in ids]))
        upper_ids = [k for k in ids if segments[k][2] < 0]  # decreasing torque
        lower_ids = [k for k in ids if segments[k][2] > 0]  # increasing torque
        if not upper_ids or not lower_ids:
            dropped.append(
                f"{len(ids)} ramp(s) of amplitude {amp:.3g} N·m all in one direction (no loop)"
            )
            dropped_amplitudes.append(amp)
            continue
        grid = np.linspace(*_shared_range(smooth, segments, ids), n_grid)

        def curves(sel: list[int]) -> np.ndarray:
            return _branch_curves(smooth, theta, segments, sel, grid, sigma)

        classes.append(
            AmplitudeClass(
                amplitude_Nm=amp,
                torque_Nm=grid,
                upper_each_rad=curves(upper_ids),
                lower_each_rad=curves(lower_ids),
                segment_ids=tuple(ids),
                centre_Nm=0.5 * float(np.median([extent[k][0] for k in ids]) + np.median([extent[k][1] for k in ids])),
            )
        )
    off_centre = _repeated_lopsided(lopsided)
    if not classes:
        why = f"; {_off_centre_text(*off_centre[0])}" if off_centre else ""
        raise InputError(
            f"hysteresis run {name!r}: no full cycle found (no increasing and decreasing torque "
            f"ramps of one amplitude crossing zero torque){why}; expected ramps between a negative "
            f"and a positive peak"
        )
    return CycleClasses(smooth, tuple(segments), tuple(classes), tuple(dropped), tuple(dropped_amplitudes), sigma,
                        off_centre)


#: ramps off centre, up and down, are one repeated cycle when their troughs and peaks agree
#: within this fraction of the ramp's torque span
_OFF_CENTRE_MATCH = 0.2


def _repeated_lopsided(lopsided: list[tuple[float, float, int]]) -> tuple[tuple[float, float], ...]:
    """(trough, peak) of each set of zero-crossing ramps too lopsided to be cycle branches that
    holds an increasing and a decreasing ramp between one trough and one peak (within
    :data:`_OFF_CENTRE_MATCH` of the span): cycles about another torque than zero. A transition
    from one amplitude to another (−4 → +25 N·m) runs once and has no such partner."""
    out = []
    for lo, hi, direction in lopsided:
        if direction < 0:
            continue
        tol = _OFF_CENTRE_MATCH * (hi - lo)
        if any(d < 0 and abs(l2 - lo) <= tol and abs(h2 - hi) <= tol for l2, h2, d in lopsided):
            if not any(abs(l2 - lo) <= tol and abs(h2 - hi) <= tol for l2, h2 in out):
                out.append((lo, hi))
    return tuple(out)


def _off_centre_text(lo: float, hi: float) -> str:
    centre = 0.5 * (lo + hi)
    return (f"its ramps from {lo:.3g} to {hi:+.3g} N·m cycle about {centre:+.3g} N·m, too far off zero torque to be "
            f"read as cycles about it — is the torque's zero offset (a load cell's zero, or a motor-current estimate's)?")


def class_loading_rate(classes: CycleClasses, cls: AmplitudeClass, time_s) -> float | None:
    """Loading rate (N·m/s) of the ramps of ``cls``, a class of ``classes`` read from a record
    with sample times ``time_s`` (s): per ramp, the amplitude over the time its smoothed torque
    takes from −A/2 to +A/2 (clear of the reversals and of a torque plateau at the peaks); the
    median over the ramps. None when no ramp has a positive duration there."""
    t = np.asarray(time_s, float)
    smooth, half = classes.smoothed_torque_Nm, 0.5 * cls.amplitude_Nm
    rates = []
    for k in cls.segment_ids:
        start, stop, direction = classes.segments[k]
        rising = direction * smooth[start : stop + 1]
        if rising.max() < half or rising.min() > -half:
            continue
        i0, i1 = start + int(np.argmax(rising >= -half)), start + int(np.argmax(rising >= half))
        if t[i1] > t[i0]:
            rates.append(2.0 * half / (t[i1] - t[i0]))
    return float(np.median(rates)) if rates else None


def small_cycle_rows(time_s, torque_Nm, angle_rad, *, name: str = "run") -> np.ndarray:
    """Which samples (bool, one per sample) of a hysteresis record belong to its smallest
    cycles — the play ramps of a bench that runs small cycles before large ones: the monotone
    torque segments of :func:`cycle_classes` whose peak |torque| lies below the geometric mean
    of the smallest class's amplitude and the next one's (a virgin loading to the small peak
    counts; a ramp from a small trough to a large peak does not). All False when the record
    has fewer than two amplitude classes (or none)."""
    out = np.zeros(np.size(torque_Nm), dtype=bool)
    try:
        classes = cycle_classes(time_s, torque_Nm, angle_rad, name=name)
    except InputError:
        return out
    if len(classes.classes) < 2:
        return out
    limit = float(np.sqrt(classes.classes[0].amplitude_Nm * classes.classes[1].amplitude_Nm))
    peak = np.abs(classes.smoothed_torque_Nm)
    for start, stop, _ in classes.segments:
        if float(peak[start:stop + 1].max()) <= limit:
            out[start:stop + 1] = True
    return out


def grouped_cycles(runs) -> list[CycleClasses]:
    """:func:`cycle_classes` of every hysteresis run whose cycles can be grouped (the others,
    e.g. a run with no full cycle, are left out)."""
    out = []
    for run in runs:
        try:
            out.append(cycle_classes(run.time_s, run.torque_Nm, run.angle_rad, name=run.name))
        except InputError:
            continue
    return out


# ----------------------------------------------------------------------------- play, loading slope

#: the loading-slope fit ends at this fraction of the class's peak on each side. The data
#: authors' slope runs "beyond the play" with no end named; on the measured loops, ending at the
#: peak reproduces their + and − compliances closer than ending at 80 or 90 % of it
#: (docs/measured/metrics-vs-authors.md, scripts/measured_metrics.py). A torque plateau at a
#: saturating bench's peak is one point of the resampled torque grid: it does not pull the slope.
LOADING_FIT_TOP = 1.0
#: the loading-slope fit must start below this fraction of the peak (else too little of the
#: branch lies beyond the play for a slope)
LOADING_FIT_MAX_START = 0.5


@dataclass(frozen=True)
class LoadingFit:
    """Least-squares loading compliances of one amplitude class (SI: rad/N·m, N·m).

    ``compliance_pos``: slope dθ/dτ of the increasing-torque branch over
    ``start_pos_Nm ≤ τ ≤ end_pos_Nm``; ``compliance_neg``: slope of the decreasing-torque
    branch over ``−end_neg_Nm ≤ τ ≤ −start_neg_Nm`` (both positive numbers for a loop whose
    angle grows with torque). ``centre_rad`` is the loop midpoint at zero torque the play
    threshold is measured from, ``play_rad`` the play used.
    """

    compliance_pos: float
    compliance_neg: float
    start_pos_Nm: float
    end_pos_Nm: float
    start_neg_Nm: float
    end_neg_Nm: float
    centre_rad: float
    play_rad: float
    amplitude_Nm: float

    @property
    def compliance(self) -> float:
        """Mean of the + and − compliances (rad/N·m), as the data authors average them."""
        return 0.5 * (self.compliance_pos + self.compliance_neg)

    @property
    def stiffness(self) -> float:
        """``1 / compliance`` (N·m/rad): the loading stiffness."""
        return 1.0 / self.compliance


def play_of(cls: AmplitudeClass) -> float:
    """Loop width in angle at zero torque of one amplitude class (rad): θ_down(0) − θ_up(0),
    the mean decreasing-torque branch minus the mean increasing-torque branch."""
    return float(np.interp(0.0, cls.torque_Nm, cls.width_rad))


def _loop_centre_and_half_play(cls: AmplitudeClass, play_rad: float) -> tuple[float, float]:
    """(θ_mid(0), play/2) in rad: the loop midpoint at zero torque the loading fits measure
    the angle from, and the threshold past which a branch counts as loaded."""
    grid = cls.torque_Nm
    centre = 0.5 * float(np.interp(0.0, grid, cls.upper_rad) + np.interp(0.0, grid, cls.lower_rad))
    return centre, 0.5 * max(float(play_rad), 0.0)


def _side_fit(
    cls: AmplitudeClass, branch: np.ndarray, side: str, centre: float, half: float, top: float, name: str
) -> tuple[float, float, float]:
    """(slope, start, end) of one loading branch of ``cls`` (:func:`loading_fit`): ``side``
    "pos" for an increasing-torque branch read at τ > 0, "neg" for a decreasing-torque branch
    read at τ < 0 and mirrored to τ > 0; fitted from the first torque beyond which the branch
    stays past ``half`` the play from ``centre`` up to ``top`` × its peak."""
    grid = cls.torque_Nm
    if side == "pos":
        tau, theta, where = grid, branch - centre, "positive"
    else:
        tau, theta, where = -grid[::-1], -(branch[::-1] - centre), "negative"
    amplitude = cls.amplitude_Nm
    peak = float(tau[-1])
    end = top * peak
    part = (tau > 0) & (tau <= end)
    t, th = tau[part], theta[part]
    inside = np.flatnonzero(th < half)
    first = 0 if inside.size == 0 else inside[-1] + 1
    if peak <= 0 or first >= t.size or t[first] > LOADING_FIT_MAX_START * peak:
        reached = (
            f"never gets past half the play ({half * 180 / math.pi:.3g}°) below "
            f"{top:g} × its peak {peak:.3g} N·m"
            if first >= t.size
            else f"gets past half the play ({half * 180 / math.pi:.3g}°) only at "
            f"{t[first]:.3g} N·m, above {LOADING_FIT_MAX_START:g} × its peak {peak:.3g} N·m"
        )
        raise InputError(
            f"hysteresis run {name!r}: the {where} loading branch of the "
            f"±{amplitude:.3g} N·m cycles {reached}; expected a loading range beyond "
            f"the play for a slope"
        )
    t, th = t[first:], th[first:]
    if t.size < 3:
        raise InputError(
            f"hysteresis run {name!r}: too few torque grid points on the {where} loading branch"
        )
    slope = float(np.polyfit(t, th, 1)[0])
    if not slope > 0:
        raise InputError(
            f"hysteresis run {name!r}: the {where} loading branch does not twist further with "
            f"torque beyond the play (slope {slope:.3g} rad/N·m); check the angle sign"
        )
    return slope, float(t[0]), float(t[-1])


def loading_fit(
    cls: AmplitudeClass, play_rad: float, *, name: str = "run", top: float = LOADING_FIT_TOP
) -> LoadingFit:
    """Loading-branch compliances of ``cls`` beyond the play (:func:`loading_compliance_from_arrays`).

    The loading branches are the increasing-torque branch for τ > 0 and the decreasing-torque
    branch for τ < 0 (|τ| growing away from zero). With θ_c = θ − θ_mid(0), θ_mid(0) the loop
    midpoint at zero torque, a side's fit starts at the first grid torque beyond which the
    branch stays past half the play (θ_c ≥ play/2 on the + side, θ_c ≤ −play/2 on the − side):
    there the gap has been crossed and the mesh is loaded. It ends at ``top`` × the class's
    peak on that side, which keeps a torque plateau at the peak out of the fit. Raises
    :class:`InputError` when a side has no such range starting below
    ``LOADING_FIT_MAX_START`` × its peak, or its slope is not positive.
    """
    centre, half = _loop_centre_and_half_play(cls, play_rad)
    out = {side: _side_fit(cls, branch, side, centre, half, top, name) for side, branch in (("pos", cls.lower_rad), ("neg", cls.upper_rad))}
    return LoadingFit(
        compliance_pos=out["pos"][0],
        compliance_neg=out["neg"][0],
        start_pos_Nm=out["pos"][1],
        end_pos_Nm=out["pos"][2],
        start_neg_Nm=out["neg"][1],
        end_neg_Nm=out["neg"][2],
        centre_rad=centre,
        play_rad=float(play_rad),
        amplitude_Nm=cls.amplitude_Nm,
    )


def play_from_arrays(time_s, torque_Nm, angle_rad, *, name: str = "run") -> float:
    """Play (rad) of a hysteresis record: the loop width at zero torque of its smallest cycles.

    Array level (no Campaign objects): ``time_s`` (s), ``torque_Nm`` (N·m), ``angle_rad`` (rad),
    1-D of one length. The record is split into monotone torque ramps and its cycles grouped by
    amplitude (:func:`cycle_classes`); the class of smallest amplitude — the play ramps a bench
    runs before its stiffness ramps, or the only class there is — is resampled on the torque
    range its branches share, averaged by direction, and the play is the width θ_down(0) −
    θ_up(0) between its decreasing- and increasing-torque branch at zero torque. This is the
    data authors' play ("the deflection jump between the start of the rising positive slope
    and the start of the rising negative slope of the small-ramp loop"). It includes whatever
    friction holds the loop open at zero torque: the data cannot separate gap from friction.
    """
    return play_of(cycle_classes(time_s, torque_Nm, angle_rad, name=name).play_class(name))


def loading_compliance_from_arrays(
    time_s, torque_Nm, angle_rad, *, play_rad: float | None = None, name: str = "run"
) -> tuple[float, float]:
    """Loading compliances ``(positive, negative)`` (rad/N·m) of a hysteresis record.

    Array level (no Campaign objects), arguments as :func:`play_from_arrays`. The catalog and
    data authors' definition: on the largest-amplitude cycles (the stiffness ramps), the slope
    of angle against torque of the *loading* branches — increasing torque for τ > 0,
    decreasing torque for τ < 0 — fitted by least squares from where the branch has crossed
    the play (its angle from the loop midpoint at zero torque is past half the play) to the
    peak, separately for + and − (:func:`loading_fit`). ``play_rad`` defaults to the loop
    width at zero torque of the record's smallest full cycles (:func:`play_from_arrays`, or
    where the play ramps form no loop the next cycles' width). The loading stiffness is
    ``1 / mean(positive, negative)``: the authors average compliances, not stiffnesses.
    """
    classes = cycle_classes(time_s, torque_Nm, angle_rad, name=name)
    play = play_of(classes.smallest) if play_rad is None else float(play_rad)
    fit = loading_fit(classes.loading_class(name), play, name=name)
    return fit.compliance_pos, fit.compliance_neg


def loading_compliance_cycles(
    cls: AmplitudeClass, play_rad: float, *, name: str = "run", top: float = LOADING_FIT_TOP
) -> tuple[np.ndarray, np.ndarray]:
    """Loading compliances branch by branch (rad/N·m): ``(positive, negative)``, the + side of
    each increasing-torque branch of ``cls`` and the − side of each decreasing-torque branch,
    in time order.

    Each branch is fitted as in :func:`loading_fit`, against the class's own loop midpoint at
    zero torque and the same play, so the branches differ only by what the bench did from
    cycle to cycle. Their spread is the repeatability of :func:`loading_fit`'s compliances:
    ``std(positive) / √n`` approximates the standard error of the class's + compliance (a
    slope is linear in the angles over a fixed range; here each branch starts where it has
    crossed the play).
    """
    centre, half = _loop_centre_and_half_play(cls, play_rad)
    pos = [_side_fit(cls, branch, "pos", centre, half, top, name)[0] for branch in cls.lower_each_rad]
    neg = [_side_fit(cls, branch, "neg", centre, half, top, name)[0] for branch in cls.upper_each_rad]
    return np.asarray(pos), np.asarray(neg)


def play_cycles(cls: AmplitudeClass) -> np.ndarray:
    """Loop width at zero torque cycle by cycle (rad): the k-th decreasing-torque branch of
    ``cls`` minus its k-th increasing-torque branch, for k up to the smaller count. A cycle's two
    branches are neighbours in time, so a walk of the whole loop in angle from ramp to ramp moves
    both alike and cancels; their spread is the bench's cycle-to-cycle repeatability of
    :func:`play_of` (which averages the branches first)."""
    n = min(cls.n_upper, cls.n_lower)
    at_zero = lambda rows: np.array([np.interp(0.0, cls.torque_Nm, row) for row in rows[:n]])  # noqa: E731
    return at_zero(cls.upper_each_rad) - at_zero(cls.lower_each_rad)


@dataclass(frozen=True)
class Reading:
    """A value read off the data (SI) and its standard error from the cycle-to-cycle scatter
    (None when fewer than two cycles give it)."""

    value: float
    se: float | None


def cycle_se(x: np.ndarray) -> float | None:
    """Standard error of the mean of per-cycle values, std/√n (None with fewer than two)."""
    return float(np.std(x, ddof=1) / np.sqrt(len(x))) if len(x) >= 2 else None


def class_readings(small: AmplitudeClass, large: AmplitudeClass, *, name: str = "run") -> dict[str, Reading]:
    """``play`` (rad) of the cycles ``small`` and the loading compliances of the cycles
    ``large`` beyond that play (rad/N·m: ``compliance_loading_pos`` / ``_neg`` and their mean
    ``compliance_loading``), each with its standard error from the scatter of its cycles
    (:func:`play_cycles`, :func:`loading_compliance_cycles`: std/√n; the mean's from both
    sides'). Raises :class:`InputError` as :func:`loading_fit` does."""
    play = play_of(small)
    fit = loading_fit(large, play, name=name)
    pos, neg = loading_compliance_cycles(large, play, name=name)
    se_pos, se_neg = cycle_se(pos), cycle_se(neg)
    se_mean = None if se_pos is None or se_neg is None else 0.5 * float(np.hypot(se_pos, se_neg))
    return {
        "play": Reading(play, cycle_se(play_cycles(small))),
        "compliance_loading_pos": Reading(fit.compliance_pos, se_pos),
        "compliance_loading_neg": Reading(fit.compliance_neg, se_neg),
        "compliance_loading": Reading(fit.compliance, se_mean),
    }


# ----------------------------------------------------------------------------- metrics


class _Reader:
    """Evaluates loop curves at a torque, allowing a small extrapolation past the grid ends."""

    def __init__(self, branches: LoopBranches, who: str, limit_Nm: float):
        self.grid = branches.torque_Nm
        self.who = who  # names the run and its file in messages
        self.limit = limit_Nm  # how far past a grid end a torque may lie
        self.extrapolated: set[float] = set()

    def __call__(self, curve: np.ndarray, torque: float) -> float:
        grid = self.grid
        if grid[0] <= torque <= grid[-1]:
            return float(np.interp(torque, grid, curve))
        if torque > grid[-1] + self.limit or torque < grid[0] - self.limit:
            raise InputError(
                f"{self.who}: the loop's branches reach only "
                f"{grid[0]:.4g}..{grid[-1]:.4g} N·m in common; expected the loop to reach "
                f"{torque:+.4g} N·m"
            )
        # Within the tolerance: straight line through the outermost part of the grid.
        n = max(3, int(round(_EXTRAPOLATION_SPAN * grid.size)))
        part = slice(-n, None) if torque > grid[-1] else slice(0, n)
        slope, intercept = np.polyfit(grid[part], curve[part], 1)
        self.extrapolated.add(float(torque))
        return float(slope * torque + intercept)


def _stiffness_entries(name: str, k_si: float, note: str) -> dict:
    return {name: _entry(from_si(k_si, "stiffness", "Nm/arcmin"), "Nm/arcmin", note)}


def hysteresis_metrics(
    run: HysteresisRun,
    rated_torque_Nm: float | None,
    *,
    lost_motion_pct: float = 3.0,
    t1_Nm: float | None = None,
    t2_Nm: float | None = None,
    branches: LoopBranches | None = None,
) -> dict[str, dict]:
    """Catalog metrics of one hysteresis run, from the data alone.

    Returns ``{NAME: {"value": float, "unit": str[, "note": str]}}`` with (T_r =
    ``rated_torque_Nm``, or with None the loop's own peak: the smaller of |τ| at the two ends of
    the torque range its branches share, said in the notes; θ_up = increasing-torque branch,
    θ_down = decreasing-torque branch, θ_mid their mean, all read off :func:`loop_branches`):

    - ``stiffness_rated`` (N·m/arcmin): the paper's secant T_r / (θ_up(T_r) − θ_ref), θ_up(T_r)
      the angle at +T_r on the increasing-torque branch (the paper's θ_r, step 5) and θ_ref the
      loop midpoint at zero torque, θ_mid(0). Includes lost motion and friction: it is not
      the elastic slope. ``stiffness_rated_negative``: T_r / (θ_ref − θ_down(−T_r)).
      ``stiffness_rated_Nm_per_deg``: ``stiffness_rated`` in the paper's unit.
    - ``lost_motion`` (arcmin): θ_mid(+x % T_r) − θ_mid(−x % T_r), x = ``lost_motion_pct``
      (vendors use 3–5 %).
    - ``backlash`` (arcmin): loop width at zero torque, θ_down(0) − θ_up(0) (GB/T 35089
      wording; Harmonic Drive catalogs call the same width "hysteresis loss").
    - ``dissipated_energy`` (J): loop area ∮ τ dθ = ∫ (θ_down − θ_up) dτ over the torque range
      common to the branches, per cycle.
    - ``stiffness_elastic`` (N·m/arcmin): least-squares slope of θ_mid over T1 ≤ |τ| ≤ T_r, one
      slope with separate intercepts for the + and − sides so the lost motion between them
      does not leak into the slope.
    - ``k1``, ``k2``, ``k3`` (N·m/arcmin): secant slopes of θ_mid over [0, T1], [T1, T2],
      [T2, T_r], from the angle increments averaged over both torque signs. K1 contains any
      lost motion inside [0, T1]. T1, T2 default to 0.25 T_r and 0.75 T_r; vendors differ
      (Harmonic Drive and Nabtesco tabulate T1/T2 per size), so pass the catalog's values.
    - ``peak_torque`` / ``peak_torque_negative`` (N·m): extremes of the smoothed torque;
      ``rated_torque`` (N·m): the T_r used.

    Raises :class:`InputError` when the loop has no full cycle or does not reach ±T_r (a
    shortfall up to 2 % of T_r is bridged by linear extrapolation and said in the note).
    """
    lb = branches
    own_peak = rated_torque_Nm is None
    if own_peak:
        lb = loop_branches(run) if lb is None else lb
        t_r = min(float(lb.torque_Nm[-1]), -float(lb.torque_Nm[0]))
    else:
        t_r = float(rated_torque_Nm)
    if not (math.isfinite(t_r) and t_r > 0):
        raise InputError(f"{_who(run)}: rated torque must be > 0 N·m, got {t_r!r}")
    t1 = 0.25 * t_r if t1_Nm is None else float(t1_Nm)
    t2 = 0.75 * t_r if t2_Nm is None else float(t2_Nm)
    if not 0 < t1 < t2 < t_r:
        raise InputError(
            f"{_who(run)}: need 0 < t1_Nm < t2_Nm < rated torque, got "
            f"t1={t1:.4g}, t2={t2:.4g}, T_r={t_r:.4g} N·m"
        )
    if not 0 < lost_motion_pct < 100:
        raise InputError(f"lost_motion_pct must be between 0 and 100, got {lost_motion_pct!r}")

    lb = loop_branches(run) if lb is None else lb
    g_lo, g_hi = float(lb.torque_Nm[0]), float(lb.torque_Nm[-1])
    if g_hi < (1 - RATED_TOLERANCE) * t_r or g_lo > -(1 - RATED_TOLERANCE) * t_r:
        raise InputError(
            f"{_who(run)}: the loop never reaches the rated torque ±{t_r:.4g} N·m "
            f"(its branches share only {g_lo:.4g}..{g_hi:.4g} N·m; peaks {lb.trough_Nm:.4g} and "
            f"{lb.peak_Nm:.4g} N·m); expected full loops to ±T_r, or give the nominal peak load"
        )
    at = _Reader(lb, _who(run), RATED_TOLERANCE * t_r)
    upper, lower, mid, grid = lb.upper_rad, lb.lower_rad, lb.midline_rad, lb.torque_Nm

    # Reference: the loop midpoint at zero torque (paper inconsistency 4: say which one).
    theta_ref = 0.5 * (at(upper, 0.0) + at(lower, 0.0))
    rise_pos = at(lower, t_r) - theta_ref  # step 5 ends at +T_r on the increasing branch
    rise_neg = theta_ref - at(upper, -t_r)  # step 3 ends at −T_r on the decreasing branch
    if rise_pos <= 0 or rise_neg <= 0:
        raise InputError(
            f"{_who(run)}: the angle does not grow with torque; expected "
            f"positive torque to twist the output forward (check the angle sign)"
        )
    k_pos, k_neg = t_r / rise_pos, t_r / rise_neg

    # The paper's protocol starts unloaded (step 1 is the virgin loading from zero); its angle
    # there is the other reference TABLES.md names. Unlike θ_mid(0) it does not depend on
    # reading a steep loop (lost motion closing over a few % of T_r) at a noisy zero torque.
    from_start = None
    smooth = lb.smoothed_torque_Nm
    first = lb.segments[0] if lb.segments else None
    if (
        first is not None
        and 0 not in lb.branch_segments
        and first[2] > 0
        and abs(float(smooth[0])) < RATED_TOLERANCE * t_r
        and float(smooth[first[1]]) >= (1 - RATED_TOLERANCE) * t_r
    ):
        rise_start = at(lower, t_r) - float(np.asarray(run.angle_rad, float)[0])
        if rise_start > 0:
            from_start = t_r / rise_start

    x = lost_motion_pct / 100.0 * t_r
    lost = at(mid, x) - at(mid, -x)
    backlash = at(upper, 0.0) - at(lower, 0.0)
    energy = float(np.trapezoid(upper - lower, grid))

    # Elastic slope: one slope, separate intercepts per sign, over T1 ≤ |τ| ≤ T_r.
    num = den = 0.0
    for side in (grid >= t1, grid <= -t1):
        sel = side & (np.abs(grid) <= t_r)
        if np.count_nonzero(sel) < 3:
            raise InputError(
                f"{_who(run)}: too few grid points between T1 = {t1:.4g} N·m "
                f"and T_r on one side for the elastic slope"
            )
        dt, dth = grid[sel] - grid[sel].mean(), mid[sel] - mid[sel].mean()
        num += float(dt @ dth)
        den += float(dt @ dt)
    compliance = num / den
    if compliance <= 0:
        raise InputError(
            f"{_who(run)}: the loop midline does not rise with torque above T1"
        )

    def secant(a: float, b: float) -> float:
        # Angle increment over [a, b] and over [−b, −a], averaged, then ΔT over it.
        dtheta = 0.5 * ((at(mid, b) - at(mid, a)) + (at(mid, -a) - at(mid, -b)))
        if dtheta <= 0:
            raise InputError(
                f"{_who(run)}: the loop midline does not rise between "
                f"{a:.4g} and {b:.4g} N·m"
            )
        return (b - a) / dtheta

    k1, k2, k3 = secant(0.0, t1), secant(t1, t2), secant(t2, t_r)

    ext = ""
    if at.extrapolated:
        ext = (
            f"; the loop's common range {grid[0]:.4g}..{grid[-1]:.4g} N·m falls short of ±T_r, "
            f"values at ±T_r extrapolated linearly"
        )
    scale = ""
    if own_peak:
        scale = (
            f"; no rated torque given: T_r = {t_r:.4g} N·m is the loop's own peak (the torque "
            f"range its branches share)"
        )
        ext += scale
    ref_note = (
        f"secant T_r/(θ(T_r) − θ_ref) at T_r = {t_r:.4g} N·m, θ(T_r) on the increasing-torque "
        f"branch (paper step 5), θ_ref the loop midpoint at zero torque; includes lost motion "
        f"and friction, not the elastic slope{ext}"
    )
    neg_note = (
        f"secant T_r/(θ_ref − θ(−T_r)), θ(−T_r) on the decreasing-torque branch (paper step 3), "
        f"θ_ref the loop midpoint at zero torque{ext}"
    )
    stiff = lambda k: from_si(k, "stiffness", "Nm/arcmin")  # noqa: E731
    arcmin = lambda a: from_si(a, "angle", "arcmin")  # noqa: E731
    n_loops = f"{lb.n_lower} increasing and {lb.n_upper} decreasing branches averaged"
    secant_note = "loop-midline secant, both torque signs (T1, T2 are vendor-specific), over"
    out = {
        "stiffness_rated": _entry(stiff(k_pos), "Nm/arcmin", ref_note),
        "stiffness_rated_negative": _entry(stiff(k_neg), "Nm/arcmin", neg_note),
        "stiffness_rated_Nm_per_deg": _entry(
            from_si(k_pos, "stiffness", "Nm/deg"), "Nm/deg", "stiffness_rated in the paper's unit"
        ),
        "stiffness_elastic": _entry(
            stiff(1.0 / compliance),
            "Nm/arcmin",
            f"least-squares slope of the loop midline over {t1:.4g} ≤ |τ| ≤ {t_r:.4g} N·m, "
            f"separate intercepts per torque sign{scale}",
        ),
        "k1": _entry(stiff(k1), "Nm/arcmin", f"{secant_note} 0..T1 = 0..{t1:.4g} N·m"),
        "k2": _entry(stiff(k2), "Nm/arcmin", f"{secant_note} T1..T2 = {t1:.4g}..{t2:.4g} N·m"),
        "k3": _entry(
            stiff(k3), "Nm/arcmin", f"{secant_note} T2..T_r = {t2:.4g}..{t_r:.4g} N·m{ext}"
        ),
        "lost_motion": _entry(
            arcmin(lost),
            "arcmin",
            f"twist between loop midpoints at ±{lost_motion_pct:g} % of T_r (±{x:.4g} N·m){scale}",
        ),
        "backlash": _entry(
            arcmin(backlash),
            "arcmin",
            "loop width in angle at zero torque (GB/T 35089 wording; Harmonic Drive catalogs "
            f"call the same width 'hysteresis loss'); {n_loops}",
        ),
        "dissipated_energy": _entry(
            energy,
            "J",
            f"loop area per cycle over {grid[0]:.4g}..{grid[-1]:.4g} N·m",
        ),
        "peak_torque": _entry(lb.peak_Nm, "Nm", "highest smoothed torque reached"),
        "peak_torque_negative": _entry(lb.trough_Nm, "Nm", "lowest smoothed torque reached"),
        "rated_torque": _entry(t_r, "Nm", f"the T_r these metrics refer to{scale}"),
    }
    if from_start is not None:
        start_note = (
            f"secant T_r/(θ(T_r) − θ_start) at T_r = {t_r:.4g} N·m, θ(T_r) on the increasing-torque "
            f"branch (paper step 5), θ_start the angle at the first sample, unloaded, before step 1 "
            f"(the paper's protocol reference){ext}"
        )
        out["stiffness_rated_from_start"] = _entry(stiff(from_start), "Nm/arcmin", start_note)
        out["stiffness_rated_from_start_Nm_per_deg"] = _entry(
            from_si(from_start, "stiffness", "Nm/deg"), "Nm/deg", "stiffness_rated_from_start in the paper's unit"
        )
    return out


# ----------------------------------------------------------------------------- one run, every metric

#: the metrics :func:`hysteresis_metrics` gives from the full-range loop (named in notes when
#: that loop cannot be read)
LOOP_METRICS = (
    "stiffness_rated",
    "stiffness_rated_negative",
    "stiffness_elastic",
    "k1",
    "k2",
    "k3",
    "lost_motion",
    "backlash",
    "dissipated_energy",
)
#: the metrics of the amplitude classes (:func:`play_from_arrays`, :func:`loading_fit`)
CLASS_METRICS = ("play", "stiffness_loading", "compliance_loading_pos", "compliance_loading_neg")
#: a play narrower than this many steps of the angle's quantisation carries a note: it is read
#: to about a step (REAL split preload3-pos1 re-quantised to 158″ steps, its play 3.6 of them,
#: read 11 % low; at their own 19.8″ steps the measured plays span 18 or more)
PLAY_STEPS_NOTE = 10.0
#: a play whose cycles centre further than this fraction of their amplitude off zero torque
#: carries a note: the width at zero torque moves with the torque's zero (the measured
#: cycloidal play ramps centre within 2 % of their amplitude)
PLAY_CENTRE_NOTE_FRACTION = 0.1
#: ... and a loading slope whose cycles centre further than this fraction of their amplitude off
#: zero (REAL split preload1-pos1 with its torque shifted 1.5 N·m, 3.8 % of its ±40 N·m ramps:
#: the slope moved by 4.8 %; the measured stiffness ramps centre within 1.9 %)
LOADING_CENTRE_NOTE_FRACTION = 0.03
#: a run whose only amplitude class stays below this fraction of the rated torque holds play
#: ramps, no stiffness ramps: its loading slope is not reported
STIFFNESS_RAMP_FRACTION = 0.5


def _off_zero_text(cls: AmplitudeClass) -> str:
    """How far ``cls``'s cycles centre off zero torque, for a metric's note."""
    return (f"these cycles centre at {cls.centre_Nm:+.3g} N·m, {100 * abs(cls.centre_Nm) / cls.amplitude_Nm:.0f} % "
            f"of their amplitude off zero torque")


def _class_metrics(run: HysteresisRun, rated_torque_Nm: float | None) -> tuple[dict, dict]:
    """``play``, ``stiffness_loading`` and the loading compliances of one run, with notes for
    those that cannot be computed."""
    out: dict[str, dict] = {}
    notes: dict[str, str] = {}
    try:
        classes = cycle_classes(run.time_s, run.torque_Nm, run.angle_rad, name=run.name)
    except InputError as err:
        return out, {name: str(err) for name in CLASS_METRICS}
    small, large = classes.smallest, classes.largest
    # one class, and no ramps of another amplitude that formed no loop
    single = len(classes.classes) == 1 and not classes.dropped_amplitudes_Nm
    deg = lambda a: from_si(a, "angle", "deg")  # noqa: E731
    no_play = classes.no_play_reason(run.name)  # the play ramps form no loop: no play, the loading slope still
    play = play_of(small)
    if play < 0:
        # friction and gap open a loop the other way: a negative width is a reversed sign
        # (the manifest's reader stops such a run; arrays given directly reach this)
        why = (f"hysteresis run {run.name!r}: the smallest cycles' loop width at zero torque is "
               f"{from_si(play, 'angle', 'arcmin'):.4g} arcmin, below zero (the decreasing-torque branch "
               f"under the increasing one: a loop run the wrong way round); expected the angle to grow with "
               f"torque (check the angle and torque signs)")
        return out, {name: why for name in CLASS_METRICS}
    amplitudes = ", ".join(f"±{c.amplitude_Nm:.3g}" for c in classes.classes)
    play_note = (
        f"loop width at zero torque (decreasing- minus increasing-torque branch) of the "
        f"smallest cycles, ±{small.amplitude_Nm:.3g} N·m ({small.n_lower} increasing and "
        f"{small.n_upper} decreasing ramps averaged; amplitude classes in the run: {amplitudes} "
        f"N·m); the data authors' play, {deg(play):.4g}°"
    )
    step = quantisation_step(run.angle_rad)
    if step is not None and play < PLAY_STEPS_NOTE * step:
        play_note += (
            f"; the play spans {play / step:.1f} steps of the angle's quantisation ({from_si(step, 'angle', 'arcsec'):.3g} "
            f"arcsec): read to about a step"
        )
    if abs(small.centre_Nm) > PLAY_CENTRE_NOTE_FRACTION * small.amplitude_Nm:
        play_note += f"; {_off_zero_text(small)}: a torque zero offset moves the play read at zero torque"
    if single:
        play_note += (
            "; the run has one amplitude class only: if these are large stiffness ramps rather "
            "than small play ramps, this is their loop width at zero torque (backlash), which "
            "friction at the larger load widens"
        )
    if no_play is None:
        out["play"] = _entry(from_si(play, "angle", "arcmin"), "arcmin", play_note)
    else:
        notes["play"] = no_play

    small_only = (
        single
        and rated_torque_Nm is not None
        and large.amplitude_Nm < STIFFNESS_RAMP_FRACTION * float(rated_torque_Nm)
    )
    no_loading = classes.no_loading_reason(run.name)
    if no_loading is not None:  # the stiffness ramps form no loop: the smaller cycles' slope is not theirs
        notes.update({name: no_loading for name in CLASS_METRICS[1:]})
        return out, notes
    if small_only:
        why = (
            f"the run's only cycles reach ±{large.amplitude_Nm:.3g} N·m, under "
            f"{STIFFNESS_RAMP_FRACTION:g} × the rated torque {float(rated_torque_Nm):.4g} N·m: play "
            f"ramps, no stiffness ramps to read a loading slope from"
        )
        notes.update({name: why for name in CLASS_METRICS[1:]})
        return out, notes
    try:
        fit = loading_fit(large, play, name=run.name)
    except InputError as err:
        notes.update({name: str(err) for name in CLASS_METRICS[1:]})
        return out, notes
    where = (
        f"of the largest cycles, ±{large.amplitude_Nm:.3g} N·m ({large.n_lower} increasing and "
        f"{large.n_upper} decreasing ramps averaged)"
    )
    if single and no_play is None:
        where += "; the run has one amplitude class only, no separate play ramps"
    span = (
        f"least squares of angle on torque from where the branch is past half the play "
        f"(±{deg(play) / 2:.3g}° from the loop midpoint at zero torque) to {100 * LOADING_FIT_TOP:g} % "
        f"of the peak"
    )
    if no_play is not None:
        span += (f"; the play ramps form no loop: half the ±{small.amplitude_Nm:.3g} N·m cycles' width "
                 f"stands for half the play")
    if abs(large.centre_Nm) > LOADING_CENTRE_NOTE_FRACTION * large.amplitude_Nm:
        span += f"; {_off_zero_text(large)}: a torque zero offset shifts the ranges the + and − slopes are read over"
    out["stiffness_loading"] = _entry(
        from_si(fit.stiffness, "stiffness", "Nm/arcmin"),
        "Nm/arcmin",
        f"catalog / data authors' definition: 1 / mean of the + and − loading-branch "
        f"compliances {where}; {span}",
    )
    out["compliance_loading_pos"] = _entry(
        deg(fit.compliance_pos),
        "deg/Nm",
        f"slope of the increasing-torque branch over {fit.start_pos_Nm:.3g}..{fit.end_pos_Nm:.3g} "
        f"N·m {where}",
    )
    out["compliance_loading_neg"] = _entry(
        deg(fit.compliance_neg),
        "deg/Nm",
        f"slope of the decreasing-torque branch over −{fit.end_neg_Nm:.3g}..−{fit.start_neg_Nm:.3g} "
        f"N·m {where}",
    )
    return out, notes


def hysteresis_run_metrics(
    run: HysteresisRun,
    rated_torque_Nm: float | None,
    *,
    lost_motion_pct: float = 3.0,
    t1_Nm: float | None = None,
    t2_Nm: float | None = None,
) -> tuple[dict[str, dict], dict[str, str]]:
    """Every data-only metric of one hysteresis run that can be computed, and a note for each
    that cannot: ``(metrics, notes)``, ``metrics`` as :func:`hysteresis_metrics` returns them and
    ``notes`` ``{NAME: one-line reason}``. Never all-or-nothing.

    ``rated_torque_Nm`` is the reducer's rated torque (None: not given).

    - :func:`hysteresis_metrics` on the full-range loop (:func:`loop_branches`: the largest
      cycles of a run that also holds small play ramps) at T_r = the rated torque, or the run's
      nominal peak load ``peak_torque_Nm`` when that is lower or no rated torque is given, or,
      with neither or for a run declared partial-load (``peak_torque_Nm = "data"``), at the
      loop's own peak (said in the notes);
    - ``play`` from the smallest cycles (:func:`play_from_arrays`);
    - ``stiffness_loading`` (N·m/arcmin) and ``compliance_loading_pos`` /
      ``compliance_loading_neg`` (deg/N·m) from the largest cycles (:func:`loading_fit`). A
      run with one amplitude class below ``STIFFNESS_RAMP_FRACTION`` × the rated torque holds
      play ramps only: no loading slope, a note instead.
    """
    metrics: dict[str, dict] = {}
    notes: dict[str, str] = {}
    rated = None if rated_torque_Nm is None else float(rated_torque_Nm)
    peak = getattr(run, "peak_torque_Nm", None)
    if getattr(run, "peak_from_data", False):  # a partial-load run (peak_torque_Nm = "data")
        t_r = None
    else:
        t_r = rated if peak is None else float(peak) if rated is None else min(rated, float(peak))
    try:
        metrics.update(
            hysteresis_metrics(
                run, t_r, lost_motion_pct=lost_motion_pct, t1_Nm=t1_Nm, t2_Nm=t2_Nm
            )
        )
    except InputError as err:
        notes.update({name: str(err) for name in LOOP_METRICS})
    extra, extra_notes = _class_metrics(run, rated_torque_Nm)
    metrics.update(extra)
    notes.update(extra_notes)
    return metrics, notes
