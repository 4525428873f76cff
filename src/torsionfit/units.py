"""Unit conversion. SI inside (rad, N·m, s); industry units at the edges (arcmin, N·m/arcmin)."""

import math

import numpy as np

from ._errors import InputError

#: radians per unit of angle
ANGLE_UNITS: dict[str, float] = {
    "rad": 1.0,
    "deg": math.pi / 180.0,
    "arcmin": math.pi / (180.0 * 60.0),
    "arcsec": math.pi / (180.0 * 3600.0),
    "rev": 2.0 * math.pi,
}
#: newton-metres per unit of torque
TORQUE_UNITS: dict[str, float] = {"Nm": 1.0, "kNm": 1e3, "Nmm": 1e-3}
#: seconds per unit of time
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "min": 60.0}
#: (N·m/rad) per unit of torsional stiffness
STIFFNESS_UNITS: dict[str, float] = {
    "Nm/rad": 1.0,
    "Nm/deg": 180.0 / math.pi,
    "Nm/arcmin": 180.0 * 60.0 / math.pi,
    "Nm/arcsec": 180.0 * 3600.0 / math.pi,
}
#: rad/s per unit of speed
SPEED_UNITS: dict[str, float] = {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0, "deg/s": math.pi / 180.0}
TEMPERATURE_UNITS: dict[str, float] = {"C": 1.0}
ENERGY_UNITS: dict[str, float] = {"J": 1.0, "mJ": 1e-3}

_QUANTITIES = {
    "angle": ANGLE_UNITS,
    "torque": TORQUE_UNITS,
    "time": TIME_UNITS,
    "stiffness": STIFFNESS_UNITS,
    "speed": SPEED_UNITS,
    "temperature": TEMPERATURE_UNITS,
    "energy": ENERGY_UNITS,
}


def factor(quantity: str, unit: str, where: str = "") -> float:
    """SI value of one ``unit`` of ``quantity``; InputError naming ``where`` if unknown."""
    table = _QUANTITIES[quantity]
    if unit not in table:
        at = f"{where}: " if where else ""
        raise InputError(
            f"{at}unknown {quantity} unit {unit!r}; expected one of {', '.join(table)}"
        )
    return table[unit]


def quantity_of(unit: str, where: str = "") -> str:
    """The quantity (``"angle"``, ``"stiffness"``, …) ``unit`` measures; InputError naming
    ``where`` if no quantity has it."""
    for quantity, table in _QUANTITIES.items():
        if unit in table:
            return quantity
    at = f"{where}: " if where else ""
    known = "; ".join(f"{q}: {', '.join(t)}" for q, t in _QUANTITIES.items())
    raise InputError(f"{at}unknown unit {unit!r}; expected one of ({known})")


def to_si(values, quantity: str, unit: str, where: str = ""):
    """Convert ``values`` given in ``unit`` to SI."""
    return np.asarray(values, dtype=float) * factor(quantity, unit, where) if not np.isscalar(
        values
    ) else float(values) * factor(quantity, unit, where)


def from_si(values, quantity: str, unit: str, where: str = ""):
    """Convert SI ``values`` to ``unit``."""
    f = factor(quantity, unit, where)
    return float(values) / f if np.isscalar(values) else np.asarray(values, dtype=float) / f


def convert(value: float, from_unit: str, to_unit: str, where: str = "") -> float:
    """``value`` in ``from_unit`` expressed in ``to_unit`` (both of one quantity); InputError
    naming ``where`` for an unknown unit or units of different quantities."""
    have, want = quantity_of(from_unit, where), quantity_of(to_unit, where)
    if have != want:
        at = f"{where}: " if where else ""
        raise InputError(f"{at}unit {from_unit!r} is a unit of {have}, but {to_unit!r} (expected) is a unit of {want}")
    if from_unit == to_unit:
        return float(value)
    return from_si(to_si(float(value), have, from_unit), want, to_unit)


def rpm_to_rad_per_s(speed_rpm: float) -> float:
    return speed_rpm * SPEED_UNITS["rpm"]
