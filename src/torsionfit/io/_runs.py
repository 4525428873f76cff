"""From a manifest's run entry and its file to a checked run in SI units."""

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._errors import InputError
from ._campaign import HysteresisRun, Reducer, TransmissionErrorRun
from ._columns import resolve_columns
from ._convention import check_twist_sign
from ._plausibility import (check_angle_unit, check_encoder_step, check_hysteresis, check_te_direction, check_te_ratio,
                            check_te_torque, check_torque_unit)
from ._read import Table, drop_trailing_pad, read_table, rows_passing, select_rows
from ._time_scale import check_loading_rate, check_loading_rate_at_rate, check_te_speed, check_te_speed_at_rate
from ._wrap import unwrap_full_turns

#: fewest samples a run may have after selection
MIN_SAMPLES = 10
#: a hysteresis run's largest |torque| must reach this fraction of its nominal peak load
PEAK_FRACTION = 0.9
#: ``peak_torque_Nm = "data"``: a partial-load run whose peak is read off its torque at load
PEAK_FROM_DATA = "data"


@dataclass(frozen=True)
class RunSpec:
    """What the manifest says about one run (values checked, units as in the manifest)."""

    index: int  # position in [[runs]], 0-based, for messages
    name: str
    kind: str  # "hysteresis" | "transmission_error"
    file: str  # as written in the manifest
    path: Path  # resolved against the manifest's folder
    columns: dict[str, str] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    select: dict = field(default_factory=dict)
    # hysteresis
    condition: dict = field(default_factory=dict)  # [runs.condition]: rules of the conditioning rows
    loading_rate_Nm_per_s: float | None = None
    peak_torque_Nm: float | str | None = None  # N·m, or "data": the run's own peak
    angle_sign: int = 1  # -1: the bench counts the angle the other way; negated on reading
    torque_sign: int = 1  # -1: the bench counts the torque the other way; negated on reading
    # transmission error
    speed_rpm: float | None = None
    torque_Nm: float | None = None
    direction: int | None = None
    input_speed_rpm: float | None = None  # motor speed; output speed = input / ratio
    te_convention: str = "lag_positive"  # the run's, else [instrument]'s
    zero_group: str | None = None
    sample_rate_Hz: float | None = None  # [instrument]; gives time to runs without a time column
    encoder_resolution_arcsec: float | None = None  # [instrument]; checks the angle unit, sizes a count
    input_encoder_resolution_arcsec: float | None = None  # [instrument]; sizes a count of input_angle
    # both kinds
    temperature_C: float | None = None


def read_run(spec: RunSpec, reducer: Reducer, where: str):
    """Read, select, convert and check one run. ``where`` names the manifest, run and file."""
    table = read_table(spec.path, where)
    count_arcsec = {"angle": spec.encoder_resolution_arcsec, "output_angle": spec.encoder_resolution_arcsec,
                    "input_angle": spec.input_encoder_resolution_arcsec}
    found = resolve_columns(table.header, spec.kind, spec.columns, spec.units, where,
                            timed_by_rate=spec.sample_rate_Hz is not None, count_arcsec=count_arcsec)
    if spec.select:
        table = select_rows(table, spec.select, where)
    notes = []
    used = sorted({column.name for column in found.values()})
    table, dropped = drop_trailing_pad(table, used)
    if dropped:
        notes.append(
            f"dropped {dropped} trailing row(s) where {', '.join(used)} hold no number "
            f"(a pad after the end of the data)"
        )
    if len(table) < MIN_SAMPLES:
        after = " after [runs.select]" if spec.select else ""
        raise InputError(
            f"{where}: only {len(table)} data row(s){after}; a run needs at least {MIN_SAMPLES}"
        )

    def si(canonical: str) -> np.ndarray | None:
        column = found.get(canonical)
        return None if column is None else table.numbers(column.name) * column.factor

    time = si("time")
    if time is not None:
        _check_time(time, table, found["time"].name, where)
    if spec.kind == "hysteresis":
        return _hysteresis(spec, reducer, table, si, time, found, where, notes)
    return _transmission_error(spec, reducer, si, time, found, where, notes)


def _check_time(time: np.ndarray, table: Table, column: str, where: str) -> None:
    # Equal stamps are fine (benches quantise time); only a step back means mixed-up rows.
    back = np.flatnonzero(np.diff(time) < 0)
    if back.size:
        i = back[0] + 1
        raise InputError(
            f"{where}: column {column!r} goes backwards at line {table.lines[i]} "
            f"({table.cells[column][i].strip()} after {table.cells[column][i - 1].strip()} "
            f"on line {table.lines[i - 1]}); time must not decrease"
        )


def _hysteresis(spec, reducer, table, si, time, found, where, notes) -> HysteresisRun:
    torque = si("torque")
    if spec.torque_sign == -1:
        # a torque counted the other way puts each loop's + side where its - side was: only a
        # declaration tells it from a reversed angle (both read as an angle falling with torque)
        torque = -torque
        notes.append(f"torque_sign = -1: column {found['torque'].name!r} negated on reading (positive torque twists "
                     f"the output forward)")
    from_data = spec.peak_torque_Nm == PEAK_FROM_DATA
    peak_torque_Nm = None if from_data else spec.peak_torque_Nm
    if from_data:
        # declared a partial-load run (play ramps, a selection of small cycles): its loop metrics
        # at the loop's own peak, and no nominal load to check the torque unit by
        if not (np.max(torque) > 0.0 > np.min(torque)):
            raise InputError(f"{where}: peak_torque_Nm = \"{PEAK_FROM_DATA}\" reads the loop's own peak, and column "
                             f"{found['torque'].name!r} does not change sign ({np.min(torque):.4g} to "
                             f"{np.max(torque):.4g} N·m); expected loops through zero torque")
        notes.append(f"peak_torque_Nm = \"{PEAK_FROM_DATA}\": a partial-load run (torque {np.min(torque):.4g} to "
                     f"{np.max(torque):.4g} N·m), its loop metrics at the loop's own peak; the torque unit is not "
                     f"checked against a nominal load")
    peak = peak_torque_Nm if peak_torque_Nm is not None else reducer.rated_torque_Nm
    reached = float(np.max(np.abs(torque)))
    # Without a nominal load (no peak_torque_Nm, no rated_torque_Nm) there is nothing to reach.
    if not from_data and peak is not None and reached < PEAK_FRACTION * peak:
        origin = "peak_torque_Nm" if spec.peak_torque_Nm is not None else "rated_torque_Nm"
        raise InputError(
            f"{where}: column {found['torque'].name!r} reaches only |torque| = {reached:.4g} N·m, "
            f"below {PEAK_FRACTION} × the nominal peak load {peak:.4g} N·m ({origin}); "
            f"check the torque column and its unit, or set peak_torque_Nm for this run (its nominal peak in N·m, "
            f"or \"{PEAK_FROM_DATA}\" for the peak its cycles reach)"
        )
    if time is not None:
        check_loading_rate(time, torque, spec.loading_rate_Nm_per_s, where, found["time"].name, found["time"].unit,
                           found["torque"].name, found["torque"].unit)
    else:  # no time column: the manifest's sample rate times the run (resolve_columns made sure of one)
        check_loading_rate_at_rate(spec.sample_rate_Hz, torque, spec.loading_rate_Nm_per_s, where,
                                   found["torque"].name, found["torque"].unit)
        time = np.arange(len(torque)) / spec.sample_rate_Hz
        notes.append(f"time from [instrument] sample_rate_Hz = {spec.sample_rate_Hz:g} (no time column)")
    angle, wraps = unwrap_full_turns(si("angle"))
    if wraps:
        notes.append(f"column {found['angle'].name!r} wraps at a full turn {wraps} time(s) (an absolute encoder's "
                     f"range): unwrapped on reading")
    if spec.angle_sign == -1:
        angle = -angle
        notes.append(f"angle_sign = -1: column {found['angle'].name!r} negated on reading (positive torque twists "
                     f"the output forward)")
    check_twist_sign(time, torque, angle, where, found["angle"].name, found["torque"].name, spec.angle_sign,
                     spec.torque_sign)
    check_angle_unit(torque, angle, reducer.rated_torque_Nm, spec.encoder_resolution_arcsec, where,
                     found["angle"].name, found["angle"].unit)
    check_torque_unit(torque, angle, reducer.rated_torque_Nm, where, found["torque"].name, found["torque"].unit)
    # after the errors: a warning is for data that read cleanly
    check_hysteresis(torque, angle, reducer.rated_torque_Nm, where, found["angle"].name,
                     found["angle"].unit, found["torque"].name, reducer.ratio)
    check_encoder_step(angle, spec.encoder_resolution_arcsec, where, found["angle"].name, found["angle"].unit)
    conditioning = None
    if spec.condition:
        conditioning = rows_passing(table, spec.condition, where, "[runs.condition]")
        if conditioning.all():
            raise InputError(f"{where}: [runs.condition] matches every row; conditioning rows only drive the "
                             f"model's state, so some rows must be left to fit")
        notes.append(f"{int(conditioning.sum())} conditioning row(s) ([runs.condition]): they drive the model's "
                     f"state, out of the fit's likelihood")
    return HysteresisRun(
        name=spec.name,
        time_s=time,
        torque_Nm=torque,
        angle_rad=angle,
        loading_rate_Nm_per_s=spec.loading_rate_Nm_per_s,
        temperature_C=si("temperature"),
        source=str(spec.path),
        peak_torque_Nm=peak_torque_Nm,
        peak_from_data=from_data,
        nominal_temperature_C=spec.temperature_C,
        notes=tuple(notes),
        conditioning=conditioning,
    )


def _transmission_error(spec, reducer, si, time, found, where, notes) -> TransmissionErrorRun:
    output = si("output_angle")
    if "te" in found:
        te = si("te")
        te_column, te_unit = f"column {found['te'].name!r}", found["te"].unit
    else:
        out_col, in_col = found["output_angle"], found["input_angle"]
        if reducer.ratio is None:
            raise InputError(
                f"{where}: column {in_col.name!r} needs [reducer] ratio to compute "
                f"te = output_angle - input_angle / ratio; add ratio or give a te_<unit> column"
            )
        check_te_ratio(output, si("input_angle"), reducer.ratio, where, out_col.name, in_col.name, out_col.unit,
                       in_col.unit)
        te = output - si("input_angle") / reducer.ratio
        # the TE's size follows the two columns' unit (one unit slipped alone stops above)
        te_column, te_unit = f"columns {out_col.name!r} and {in_col.name!r}", out_col.unit
    if spec.te_convention == "lag_negative":
        te = -te
        notes.append("TE negated on reading (te_convention = 'lag_negative')")
    speed = spec.speed_rpm
    if speed is None:  # the manifest reader made sure one of the two is given, with ratio
        speed = spec.input_speed_rpm / reducer.ratio
    # Sampling at n equal steps over one turn ends one step short of 360°, so the step is
    # added to the span before comparing.
    span = float(np.ptp(output))
    step = float(np.median(np.abs(np.diff(output))))
    if span + step < 2.0 * math.pi * (1.0 - 1e-9):
        raise InputError(
            f"{where}: column {found['output_angle'].name!r} spans {math.degrees(span):.4g}°; "
            f"a transmission-error run must cover at least one output revolution (360°)"
        )
    check_te_direction(output, spec.direction, where, found["output_angle"].name)
    key = "speed_rpm" if spec.speed_rpm is not None else "input_speed_rpm / [reducer] ratio"
    if time is not None:
        check_te_speed(time, output, speed, where, found["time"].name, found["time"].unit,
                       found["output_angle"].name, found["output_angle"].unit, key)
    if time is None and spec.sample_rate_Hz is not None:
        check_te_speed_at_rate(spec.sample_rate_Hz, output, speed, where, found["output_angle"].name,
                               found["output_angle"].unit, key)
        time = np.arange(len(output)) / spec.sample_rate_Hz
        notes.append(f"time from [instrument] sample_rate_Hz = {spec.sample_rate_Hz:g} (no time column)")
    # otherwise time_s stays None: the model times the run by its speed and angle steps
    if "torque" in found:
        check_te_torque(si("torque"), spec.torque_Nm, reducer.rated_torque_Nm, where, found["torque"].name,
                        found["torque"].unit, reducer.ratio)
    return TransmissionErrorRun(
        name=spec.name,
        output_angle_rad=output,
        te_rad=te,
        torque_Nm=spec.torque_Nm,
        speed_rpm=speed,
        direction=spec.direction,
        time_s=time,
        torque_series_Nm=si("torque"),
        temperature_C=si("temperature"),
        source=str(spec.path),
        zero_group=spec.zero_group,
        te_convention=spec.te_convention,
        nominal_temperature_C=spec.temperature_C,
        notes=tuple(notes),
        te_column=te_column,
        te_unit=te_unit,
    )
