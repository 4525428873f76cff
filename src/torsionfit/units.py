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


def to_si(values, quantity: str, unit: str, where: str = ""):
    """Convert ``values`` given in ``unit`` to SI."""
    return np.asarray(values, dtype=float) * factor(quantity, unit, where) if not np.isscalar(
        values
    ) else float(values) * factor(quantity, unit, where)


def from_si(values, quantity: str, unit: str, where: str = ""):
    """Convert SI ``values`` to ``unit``."""
    f = factor(quantity, unit, where)
    return float(values) / f if np.isscalar(values) else np.asarray(values, dtype=float) / f


def rpm_to_rad_per_s(speed_rpm: float) -> float:
    return speed_rpm * SPEED_UNITS["rpm"]
