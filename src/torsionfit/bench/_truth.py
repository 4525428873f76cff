"""Truth values in a bench file: ``<parameter>_<unit>`` keys, converted to SI model parameters."""

import math

from .._errors import InputError

_RPM = 2.0 * math.pi / 60.0
_ARCMIN = math.pi / (180.0 * 60.0)
_ARCSEC = _ARCMIN / 60.0

#: unit suffix → SI factor
UNIT_SUFFIXES: dict[str, float] = {
    "Nm_per_rad": 1.0,
    "Nm_per_deg": 180.0 / math.pi,
    "Nm_per_arcmin": 1.0 / _ARCMIN,
    "Nm": 1.0,
    "rad": 1.0,
    "deg": math.pi / 180.0,
    "arcmin": _ARCMIN,
    "arcsec": _ARCSEC,
    "s": 1.0,
    "Nm_s_per_rad": 1.0,
    "Nm_per_rpm": 1.0 / _RPM,  # c_v·|v| in N·m per rpm of output speed
    "per_rpm": 1.0 / _RPM,
    "per_rpm2": 1.0 / _RPM**2,
    "s_per_rad": 1.0,
    "s2_per_rad2": 1.0,
    "arcsec_per_s": _ARCSEC,
    "arcmin_per_s": _ARCMIN,
    "per_K": 1.0,
    "": 1.0,  # dimensionless
}

#: model parameter → suffixes it accepts
ACCEPTED: dict[str, tuple[str, ...]] = {
    **{k: ("Nm_per_rad", "Nm_per_deg", "Nm_per_arcmin") for k in ("stiffness", "k1", "k2", "k3", "creep_stiffness")},
    **{k: ("Nm",) for k in ("friction_torque", "dahl_torque", "gap_torque", "gap_preload_torque", "gap_hold_torque", "gap_centre_torque", "gap_residual_torque", "gap_relay_span", "preload_lift_torque", "t1", "t2", "torque_offset", "play_torque_offset")},
    **{k: ("rad", "deg", "arcmin", "arcsec") for k in ("gap", "te_offset", "angle_offset", "elastic_rated_twist")},
    "creep_time": ("s",),
    "gap_lag_time": ("s",),
    "friction_load_lag_time": ("s",),
    "viscous_friction": ("Nm_s_per_rad", "Nm_per_rpm"),
    "speed_compliance_1": ("s_per_rad", "per_rpm"),
    "speed_compliance_2": ("s2_per_rad2", "per_rpm2"),
    "power_exponent": ("",),
    "compliance_asymmetry": ("",),
    "breakaway_spread": ("",),
    "friction_load_coefficient": ("",),
    "friction_load_memory": ("",),
    "series_share": ("",),
    "gap_residual_share": ("",),
    "preload_stiffening": ("",),
    "gap_step_logits": ("",),
    "gap_relay_logits": ("",),
    "drift": ("arcsec_per_s", "arcmin_per_s"),
    "temperature_compliance": ("per_K",),
    "temperature_friction": ("per_K",),
    "kin_cos": ("rad", "arcsec", "arcmin"),
    "kin_sin": ("rad", "arcsec", "arcmin"),
}


def parse_truth(table: dict, where: str) -> dict:
    """``{"stiffness_Nm_per_arcmin": 108, ...}`` → ``{"stiffness": 3.7e5, ...}`` (SI)."""
    out = {}
    for key, value in table.items():
        name, factor = _split(key, where)
        if name in out:
            raise InputError(f"{where}: parameter {name!r} given twice (key {key!r})")
        try:
            out[name] = [float(v) * factor for v in value] if isinstance(value, list) else float(value) * factor
        except (TypeError, ValueError):
            raise InputError(f"{where}.{key}: expected a number or a list of numbers, got {value!r}") from None
    if "t2" in out:
        out["t2_minus_t1"] = out.pop("t2") - out.get("t1", 0.0)
    return out


def _split(key: str, where: str) -> tuple[str, float]:
    for name in sorted(ACCEPTED, key=len, reverse=True):
        if key == name and "" in ACCEPTED[name]:
            return name, 1.0
        if key.startswith(name + "_"):
            suffix = key[len(name) + 1:]
            if suffix in ACCEPTED[name]:
                return name, UNIT_SUFFIXES[suffix]
            raise InputError(
                f"{where}.{key}: unit {suffix!r} not accepted for {name}; use one of "
                + ", ".join(f"{name}_{s}" if s else name for s in ACCEPTED[name])
            )
    raise InputError(f"{where}.{key}: unknown truth parameter; known: {', '.join(sorted(ACCEPTED))}")
