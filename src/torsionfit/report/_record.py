"""The model read off the data's own record: ``play`` and the loading compliances of the
fitted model's noise-free prediction of the measured torque history (denoised, as the fit
drives the model), with the data-only
definitions (``torsionfit.metrics``: the same ramps, the same torque grids, the same bins).

Everything that depends on the torque alone — the split into ramps, the amplitude classes, each
branch's torque bins and interpolation weights — is read off the data once
(``metrics.branch_weights``); what depends on the angle is then a fixed linear map of the
model's prediction (branch curves, the width at zero torque) and a least-squares slope from
where the branch has crossed half the play, vectorised over draws. A synthetic record of the
same amplitudes does not read the same: the measured torque dwells at its peaks, and a friction
level or a gap that lags the torque in time draws another loop after a dwell.
"""

from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import model as m
from .._errors import InputError
from ..fit import denoise_torque
from ..io import Campaign
from ..metrics._hysteresis import (LOADING_FIT_MAX_START, LOADING_FIT_TOP, AmplitudeClass, CycleClasses, branch_weights,
                                   cycle_classes, small_cycle_rows)


@dataclass(frozen=True)
class RecordClasses:
    """The hysteresis runs (and their cycle classes) the class metrics are read from: the run
    with the smallest cycles for ``play``, the run with the largest for the loading slope
    (often one run: play ramps, then stiffness ramps). ``play_note`` says why no ``play`` is
    read (the smallest ramps form no loop: ``CycleClasses.play_class``); ``small`` is then the
    smallest full cycles, whose width stands for the play the loading slope starts past.
    ``loading_note`` says why no loading slope is read (the largest ramps form no loop:
    ``CycleClasses.loading_class``)."""

    small_run: object
    small: AmplitudeClass
    small_classes: CycleClasses
    large_run: object
    large: AmplitudeClass
    large_classes: CycleClasses
    play_note: str | None = None
    loading_note: str | None = None


def record_classes(campaign: Campaign) -> RecordClasses | None:
    """:class:`RecordClasses` of ``campaign``; None without a hysteresis run whose cycles can
    be grouped (``metrics.cycle_classes``), or when neither the play nor the loading slope can
    be read (both the smallest and the largest ramps form no loop)."""
    grouped = []
    for run in campaign.hysteresis_runs:
        try:
            grouped.append((run, cycle_classes(run.time_s, run.torque_Nm, run.angle_rad, name=run.name)))
        except InputError:  # e.g. a run with no full cycle: left out, as the data-only metrics do
            continue
    if not grouped:
        return None
    small_run, small_classes = min(grouped, key=lambda g: g[1].smallest.amplitude_Nm)
    large_run, large_classes = max(grouped, key=lambda g: g[1].largest.amplitude_Nm)
    play_note, loading_note = small_classes.no_play_reason(small_run.name), large_classes.no_loading_reason(large_run.name)
    if play_note is not None and loading_note is not None:
        return None  # neither the play nor the loading slope: no record to read
    return RecordClasses(small_run, small_classes.smallest, small_classes, large_run, large_classes.largest, large_classes,
                         play_note, loading_note)


class _Mean(eqx.Module):
    """A class's mean branch of one direction as a linear map of the run's angle record."""

    samples: jnp.ndarray
    bins: jnp.ndarray
    counts: jnp.ndarray
    lo: jnp.ndarray
    w: jnp.ndarray

    def __call__(self, theta):
        sums = jax.ops.segment_sum(theta[self.samples], self.bins, num_segments=self.counts.shape[0])
        mean = sums / self.counts
        return jnp.mean((1.0 - self.w) * mean[self.lo] + self.w * mean[self.lo + 1], axis=0)


#: the maps' sample and bin counts are padded up to multiples of these: units of one bench
#: (the same record length and cycles, bins that differ by the noise) then share one compiled
#: program (a batch of 200 units compiled the metrics once, not 200 times)
_PAD_SAMPLES, _PAD_BINS = 512, 64


def _mean(classes: CycleClasses, cls: AmplitudeClass, direction: int) -> _Mean:
    ids = [k for k in cls.segment_ids if classes.segments[k][2] == direction]
    bw = branch_weights(classes.smoothed_torque_Nm, classes.segments, ids, cls.torque_Nm, classes.torque_noise_Nm)
    n_bins = bw.counts.size
    bins_padded = -(-(n_bins + 1) // _PAD_BINS) * _PAD_BINS  # at least one spare bin
    pad = -bw.samples.size % _PAD_SAMPLES
    # padding: sample 0 into the last (spare) bin, which no interpolation reads
    samples = np.concatenate([bw.samples, np.zeros(pad, np.int64)])
    bins = np.concatenate([bw.bins, np.full(pad, bins_padded - 1)])
    counts = np.concatenate([bw.counts, np.ones(bins_padded - n_bins)])
    return _Mean(*(jnp.asarray(a) for a in (samples, bins, counts, bw.lo, bw.w)))


def _side_slope(t, th, part, half, max_start):
    """Least-squares slope of ``th`` on ``t`` over the points of ``part`` (a contiguous mask:
    0 < t ≤ the fit's top) from the first beyond which ``th`` stays at or past ``half``
    (``metrics._side_fit``); NaN where the data-only reading raises: no such start below
    ``max_start``, fewer than three points, or a slope that is not positive."""
    idx = jnp.arange(t.shape[0])
    start = jnp.argmax(part)
    first = jnp.maximum(jnp.max(jnp.where(part & (th < half), idx, -1)) + 1, start)
    w = (part & (idx >= first)).astype(t.dtype)
    n = jnp.sum(w)
    tm, ym = jnp.sum(w * t) / jnp.maximum(n, 1.0), jnp.sum(w * th) / jnp.maximum(n, 1.0)
    slope = jnp.sum(w * (t - tm) * (th - ym)) / jnp.maximum(jnp.sum(w * (t - tm) ** 2), 1e-300)
    ok = (n >= 3) & (t[jnp.minimum(first, t.shape[0] - 1)] <= max_start) & (slope > 0)
    return jnp.where(ok, slope, jnp.nan)


class RecordReader(eqx.Module):
    """``(play, compliance_pos, compliance_neg)`` (rad, rad/N·m) of a model's prediction of
    the data's record, for any parameters: :func:`record_reader` builds it."""

    inputs: tuple  # model input per record read (one, or two when play and slope are in two runs)
    small_upper: _Mean
    small_lower: _Mean
    large_upper: _Mean
    large_lower: _Mean
    small_grid: jnp.ndarray
    large_grid: jnp.ndarray
    pos_part: jnp.ndarray  # mask of the grid: the + side's fit range
    neg_part: jnp.ndarray  # the − side's, on the mirrored grid
    large_record: int = eqx.field(static=True)  # index into ``inputs`` of the large cycles' run
    #: per input, the index of its run among the campaign's hysteresis runs: whose fitted state at
    #: its first sample the prediction starts from
    run_index: tuple = eqx.field(static=True, default=(0,))

    @property
    def n_samples(self) -> int:
        return sum(int(inp.torque_Nm.shape[0]) for inp in self.inputs)

    def read(self, model: m.CampaignModel, params: list):
        """(play, compliance_pos, compliance_neg) of ``model``'s (a one-run model's) prediction,
        ``params[k]`` the parameters of input ``k``'s run (:func:`record_params`)."""
        theta = [model.predict(p, [inp])[0] for p, inp in zip(params, self.inputs)]
        return self.read_angles(theta[0], theta[self.large_record])

    def read_angles(self, small_theta, large_theta):
        """(play, compliance_pos, compliance_neg) of the angle records (rad) of the small
        cycles' run and the large cycles' run (the same array when one run holds both)."""
        width = self.small_upper(small_theta) - self.small_lower(small_theta)
        play = jnp.interp(0.0, self.small_grid, width)
        upper, lower = self.large_upper(large_theta), self.large_lower(large_theta)
        grid = self.large_grid
        centre = 0.5 * (jnp.interp(0.0, grid, upper) + jnp.interp(0.0, grid, lower))
        half = 0.5 * jnp.maximum(play, 0.0)
        c_pos = _side_slope(grid, lower - centre, self.pos_part, half, LOADING_FIT_MAX_START * grid[-1])
        c_neg = _side_slope(-grid[::-1], -(upper[::-1] - centre), self.neg_part, half, LOADING_FIT_MAX_START * -grid[0])
        return play, c_pos, c_neg


def record_params(model: m.CampaignModel, at_rest: dict, values: dict, run_index: int) -> dict:
    """Parameters of a one-run ``model`` predicting the campaign's hysteresis run ``run_index``:
    ``at_rest`` (the run started at rest, no offsets) with that run's fitted state at its first
    sample and the torque-sensor offset from the campaign's ``values``. The record did not start
    at rest: on a loop whose slip elements break away above the play ramps' torque, the state
    they were left in holds through every play ramp (measured split preload3-pos6: the model's
    play at the MAP 8.5′ from its fitted state, 15.2′ from rest; the data's 6.2′)."""
    out = dict(at_rest)
    names = {p.name for p in model.parameters()}
    for name in m.RUN_START_STATES:
        if name in names and name in values:
            out[name] = jnp.atleast_1d(values[name])[run_index:run_index + 1]
    if "torque_offset" in names and "torque_offset" in values:
        out["torque_offset"] = values["torque_offset"]
    return out


def record_reader(classes: RecordClasses, hysteresis_runs: tuple = ()) -> RecordReader:
    """The reader of the records in ``classes`` (:func:`record_classes`); ``hysteresis_runs``:
    the campaign's hysteresis runs, in order (where the records' runs are, for their fitted
    start states; empty: the first)."""
    # the model is driven as the fit drives it: by the denoised measured torque (a play operator
    # on the raw torque slides by its noise and draws a narrower loop)
    def inp(run):
        small = small_cycle_rows(run.time_s, run.torque_Nm, run.angle_rad, name=run.name)
        return m.hysteresis_input(run.time_s, denoise_torque(run.torque_Nm), small_cycle=small)

    same = classes.large_run is classes.small_run
    inputs = (inp(classes.small_run),) if same else (inp(classes.small_run), inp(classes.large_run))
    grid = np.asarray(classes.large.torque_Nm)
    mirrored = -grid[::-1]
    pos_part = (grid > 0) & (grid <= LOADING_FIT_TOP * grid[-1])
    neg_part = (mirrored > 0) & (mirrored <= LOADING_FIT_TOP * mirrored[-1])
    return RecordReader(
        inputs=inputs,
        small_upper=_mean(classes.small_classes, classes.small, -1),
        small_lower=_mean(classes.small_classes, classes.small, 1),
        large_upper=_mean(classes.large_classes, classes.large, -1),
        large_lower=_mean(classes.large_classes, classes.large, 1),
        small_grid=jnp.asarray(classes.small.torque_Nm),
        large_grid=jnp.asarray(grid),
        pos_part=jnp.asarray(pos_part),
        neg_part=jnp.asarray(neg_part),
        large_record=0 if same else 1,
        run_index=tuple(_index_of(run, hysteresis_runs) for run in
                        ((classes.small_run,) if same else (classes.small_run, classes.large_run))),
    )


def _index_of(run, runs: tuple) -> int:
    return next((i for i, r in enumerate(runs) if r is run), 0)
