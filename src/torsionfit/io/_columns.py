"""Which file column holds which canonical quantity, and in which unit.

By default a column's name carries its unit as a suffix: ``<canonical>_<unit>``, e.g.
``torque_Nm``, ``angle_arcmin``, ``output_angle_deg``, ``te_arcsec``, ``temperature_C``.
A run may instead map canonical names to its own columns with ``[runs.columns]``; such a
column is read in the unit given by ``[runs.units]``, and in SI (rad, Nm, s; °C for
temperature) when no unit is given.

An angle logged in raw encoder counts has the unit ``count``: one count is the encoder's
resolution, ``[instrument] encoder_resolution_arcsec`` for the output encoder (``angle``,
``output_angle``) and ``[instrument] input_encoder_resolution_arcsec`` for the motor encoder
(``input_angle``). A ``te`` column has no encoder of its own, so it cannot be in counts.
"""

from dataclasses import dataclass

from .. import units
from .._errors import InputError

#: canonical column name → physical quantity (a table of units.py), per run kind
CANONICAL: dict[str, dict[str, str]] = {
    "hysteresis": {
        "time": "time",
        "torque": "torque",
        "angle": "angle",
        "temperature": "temperature",
    },
    "transmission_error": {
        "output_angle": "angle",
        "te": "angle",
        "input_angle": "angle",
        "time": "time",
        "torque": "torque",
        "temperature": "temperature",
    },
}

#: columns a run cannot do without (a TE run also needs ``te`` or ``input_angle``)
REQUIRED: dict[str, tuple[str, ...]] = {
    "hysteresis": ("time", "torque", "angle"),
    "transmission_error": ("output_angle",),
}

#: accepted units per quantity (name → SI value of one unit)
UNITS: dict[str, dict[str, float]] = {
    "angle": units.ANGLE_UNITS,
    "torque": units.TORQUE_UNITS,
    "time": units.TIME_UNITS,
    "temperature": units.TEMPERATURE_UNITS,
}

#: the unit of an angle logged in raw encoder counts (one count = the encoder's resolution)
COUNT = "count"
#: the [instrument] key giving the angle of one count, per canonical angle column
COUNT_KEYS = {"angle": "encoder_resolution_arcsec", "output_angle": "encoder_resolution_arcsec",
              "input_angle": "input_encoder_resolution_arcsec"}

#: unit of a mapped column when [runs.units] says nothing
SI_UNIT = {"angle": "rad", "torque": "Nm", "time": "s", "temperature": "C"}


@dataclass(frozen=True)
class Column:
    """One resolved column: its name in the file, its unit, and SI value of one unit."""

    name: str
    unit: str
    factor: float


def accepted_units(quantity: str) -> list[str]:
    """The units a column of ``quantity`` may be in (angles also in encoder counts)."""
    return list(UNITS[quantity]) + ([COUNT] if quantity == "angle" else [])


def _unit_list(quantity: str) -> str:
    return ", ".join(accepted_units(quantity))


def check_unit(quantity: str, unit: str, where: str) -> None:
    """InputError naming ``where`` when ``unit`` is not a unit of ``quantity``."""
    if unit not in accepted_units(quantity):
        raise InputError(f"{where}: unknown {quantity} unit {unit!r}; expected one of {_unit_list(quantity)}")


def _factor(canonical: str, quantity: str, unit: str, where: str, count_arcsec: dict[str, float | None]) -> float:
    """SI value of one ``unit`` of column ``canonical``; a count is its encoder's resolution."""
    check_unit(quantity, unit, where)
    if unit != COUNT:
        return units.factor(quantity, unit, where)
    if canonical not in COUNT_KEYS:
        raise InputError(f"{where}: a {canonical} column cannot be in encoder counts (no one encoder counts it); "
                         f"give it in an angle unit ({', '.join(units.ANGLE_UNITS)}), or map output_angle and "
                         f"input_angle and let te be computed from them")
    resolution = count_arcsec.get(canonical)
    if resolution is None:
        raise InputError(f"{where}: {canonical} in encoder counts needs [instrument] {COUNT_KEYS[canonical]} "
                         f"(the angle of one count, arcsec: 1296000 / counts per revolution)")
    return resolution * units.ANGLE_UNITS["arcsec"]


def _by_suffix(header, canonical: str, quantity: str, where: str,
               count_arcsec: dict[str, float | None]) -> Column | None:
    """The ``<canonical>_<unit>`` column, None if there is none."""
    prefix = canonical + "_"
    # dict.fromkeys: a name repeated in the header is one candidate (reading it then fails).
    candidates = [name for name in dict.fromkeys(header) if name.startswith(prefix)]
    known = [name for name in candidates if name[len(prefix) :] in accepted_units(quantity)]
    if len(known) > 1:
        raise InputError(
            f"{where}: several columns could be {canonical}: {', '.join(known)}; "
            f"keep one or choose with [runs.columns]"
        )
    if known:
        name = known[0]
    elif candidates:
        # e.g. 'angle_mrad': a typo in the unit must not make the column silently absent.
        name = candidates[0]
    else:
        return None
    unit = name[len(prefix) :]
    return Column(name, unit, _factor(canonical, quantity, unit, f"{where}: column {name!r}", count_arcsec))


def resolve_columns(
    header, kind: str, columns: dict[str, str], unit_names: dict[str, str], where: str,
    timed_by_rate: bool = False, count_arcsec: dict[str, float | None] | None = None,
) -> dict[str, Column]:
    """Find the columns of a run of ``kind`` in ``header``.

    ``columns`` and ``unit_names`` are the run's ``[runs.columns]`` and ``[runs.units]``
    tables (canonical name → file column / unit), already checked to use canonical names;
    ``timed_by_rate``: the manifest declares ``[instrument] sample_rate_Hz``, which times a run
    without a time column; ``count_arcsec``: canonical angle column → the [instrument]
    resolution one encoder count stands for (arcsec; None when not declared). Returns
    canonical name → Column for every column found; InputError
    for a required column that is missing, an unknown unit, or an ambiguous choice.
    """
    count_arcsec = count_arcsec or {}
    found: dict[str, Column] = {}
    for canonical, quantity in CANONICAL[kind].items():
        if canonical in columns:
            name = columns[canonical]
            unit = unit_names.get(canonical, SI_UNIT[quantity])
            if name not in header:
                raise InputError(
                    f"{where}: column {name!r} ([runs.columns] {canonical}) not found; "
                    f"columns are {', '.join(header)}"
                )
            at = f"{where}: [runs.units] {canonical}"
            found[canonical] = Column(name, unit, _factor(canonical, quantity, unit, at, count_arcsec))
        else:
            column = _by_suffix(header, canonical, quantity, where, count_arcsec)
            if column is not None:
                found[canonical] = column
    for canonical in REQUIRED[kind]:
        if canonical == "time" and timed_by_rate:
            continue
        if canonical not in found:
            rate = (" (or declare [instrument] sample_rate_Hz for a run sampled at a fixed rate)"
                    if canonical == "time" else "")
            raise InputError(
                f"{where}: no {canonical} column: expected {canonical}_<unit> with unit one of "
                f"{_unit_list(CANONICAL[kind][canonical])}, or a [runs.columns] entry{rate}; "
                f"columns are {', '.join(header)}"
            )
    if kind == "transmission_error":
        if "te" not in found and "input_angle" not in found:
            raise InputError(
                f"{where}: no te_<unit> or input_angle_<unit> column (unit one of "
                f"{_unit_list('angle')}), nor a [runs.columns] entry for te or input_angle; "
                f"columns are {', '.join(header)}"
            )
        if "te" in columns and "input_angle" in columns:
            raise InputError(
                f"{where}: [runs.columns] maps both te and input_angle; map one of them"
            )
        if "input_angle" in columns:
            found.pop("te", None)  # the user chose to compute te from the input angle
        elif "te" in found:
            found.pop("input_angle", None)  # a measured te column wins over computing it
    return found
