"""Block-mean decimation of densely sampled runs (an explicit, recorded choice, never silent)."""

from dataclasses import replace

import numpy as np

from .._errors import InputError
from ._campaign import Campaign, HysteresisRun, TransmissionErrorRun


def _block_mean(x, factor: int):
    if x is None:
        return None
    x = np.asarray(x, float)
    n = (len(x) // factor) * factor
    return x[:n].reshape(-1, factor).mean(axis=1)


def decimate(campaign: Campaign, factor: int) -> Campaign:
    """Each run replaced by means of ``factor`` consecutive samples (a trailing partial block
    is dropped). Benches often sample far faster than the physics changes; averaging keeps the
    loop, lowers quantisation and sensor noise per sample, and makes fits cheaper. The
    campaign's notes record it."""
    if not isinstance(factor, int) or factor < 1:
        raise InputError(f"decimation factor must be a whole number ≥ 1, got {factor!r}")
    if factor == 1:
        return campaign
    runs = []
    for run in campaign.runs:
        if len(run) // factor < 10:
            raise InputError(f"run {run.name!r}: {len(run)} samples leave fewer than 10 after decimating by {factor}")
        if isinstance(run, HysteresisRun):
            runs.append(replace(run, time_s=_block_mean(run.time_s, factor), torque_Nm=_block_mean(run.torque_Nm, factor),
                                angle_rad=_block_mean(run.angle_rad, factor),
                                temperature_C=_block_mean(run.temperature_C, factor),
                                # a block with a conditioning row is one (its mean carries it)
                                conditioning=None if run.conditioning is None else
                                _block_mean(np.asarray(run.conditioning, float), factor) > 0))
        else:
            assert isinstance(run, TransmissionErrorRun)
            # block means of an angle that wraps would be wrong: unwrap first
            phi = np.unwrap(np.asarray(run.output_angle_rad, float))
            runs.append(replace(run, output_angle_rad=_block_mean(phi, factor), te_rad=_block_mean(run.te_rad, factor),
                                time_s=_block_mean(run.time_s, factor), torque_series_Nm=_block_mean(run.torque_series_Nm, factor),
                                temperature_C=_block_mean(run.temperature_C, factor)))
    note = f"decimated by {factor} (block means of consecutive samples)"
    return replace(campaign, runs=tuple(runs), notes=f"{campaign.notes}; {note}" if campaign.notes else note)
