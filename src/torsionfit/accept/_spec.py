"""The acceptance spec file (DESIGN §4): ``p_accept`` and ``[[requirement]]`` tables, read with
strict keys, and bound to one campaign's metric catalogue (limits converted to the metric's unit).

Every message is one line naming the file, the requirement (``requirement[i]``, counted from 0)
and the key. A requirement on ``metric = "kd"`` asks K_d(τ, v) ≥ ``min`` at every torque and
speed of an operating region ``torque_Nm = [lo, hi]``, ``speed_rpm = [lo, hi]`` (TE campaigns).
"""

import math
from dataclasses import dataclass
from pathlib import Path

from .._errors import InputError
from ..io._manifest import _check_keys, _number, _read_toml, _text
from ..units import convert, quantity_of

#: the metric name of a K_d requirement over an operating region
KD = "kd"
#: the unit K_d is computed in (``DerivedMetrics.kd_over_draws``)
KD_UNIT = "Nm/arcmin"
DEFAULT_P_ACCEPT = 0.95

_TOP_KEYS = ("label", "p_accept", "requirement")
_KEYS = ("metric", "name", "min", "max", "unit")
_KD_KEYS = ("metric", "name", "min", "unit", "torque_Nm", "speed_rpm")


@dataclass(frozen=True)
class Requirement:
    """``metric`` ≥ ``limit`` (``bound = "min"``) or ≤ ``limit`` (``"max"``), ``limit`` in ``unit``.
    For ``metric == "kd"``: K_d(τ, v) ≥ ``limit`` over ``torque_range_Nm`` × ``speed_range_rpm``."""

    name: str
    metric: str
    bound: str  # "min" or "max"
    limit: float
    unit: str
    torque_range_Nm: tuple[float, float] | None = None
    speed_range_rpm: tuple[float, float] | None = None
    where: str = ""  # "spec.toml: requirement[i]", for messages

    @property
    def is_kd(self) -> bool:
        return self.metric == KD


@dataclass(frozen=True)
class Spec:
    """A parsed spec: requirements and the guarded-acceptance threshold ``p_accept``."""

    requirements: tuple[Requirement, ...]
    p_accept: float = DEFAULT_P_ACCEPT
    label: str = ""
    path: Path | None = None


@dataclass(frozen=True)
class BoundRequirement:
    """A requirement checked against one campaign's metrics: ``column`` of the metric in
    ``CampaignFit.metric_draws`` (None for K_d) and the limit in the metric's own unit."""

    requirement: Requirement
    column: int | None
    limit_in_metric_unit: float
    metric_unit: str


def load_spec(path) -> Spec:
    """Read and check a spec file (TOML); InputError (one line) on any problem."""
    path = Path(path)
    return parse_spec(_read_toml(path, "spec file"), str(path), path)


def parse_spec(doc: dict, shown: str = "spec", path: Path | None = None) -> Spec:
    """A :class:`Spec` from the TOML document ``doc``; ``shown`` names it in messages."""
    _check_keys(doc, _TOP_KEYS, shown, "the top level")
    label = _text(doc, "label", shown, default="")
    p_accept = DEFAULT_P_ACCEPT
    if "p_accept" in doc:
        p_accept = _number(doc, "p_accept", shown)
        if not 0.5 < p_accept < 1.0:
            raise InputError(f"{shown}: p_accept must be in (0.5, 1) (accept if p_c ≥ p_accept, "
                             f"reject if p_c ≤ 1 − p_accept), got {doc['p_accept']!r}")
    entries = doc.get("requirement", [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise InputError(f"{shown}: requirement must be an array of tables, written as [[requirement]]")
    if not entries:
        raise InputError(f"{shown}: the spec has no requirements; add at least one [[requirement]] "
                         f"table with metric, min or max, and unit")
    requirements = tuple(_requirement(entry, f"{shown}: requirement[{i}]") for i, entry in enumerate(entries))
    seen: dict[str, str] = {}
    for r in requirements:
        if r.name in seen:
            raise InputError(f"{r.where}: name {r.name!r} is already used by {seen[r.name]}; "
                             f"give each requirement its own name")
        seen[r.name] = r.where
    return Spec(requirements, p_accept, label, path)


def _requirement(entry: dict, where: str) -> Requirement:
    metric = _text(entry, "metric", where, required=True)
    where = f"{where} (metric {metric!r})"
    _check_keys(entry, _KD_KEYS if metric == KD else _KEYS, where,
                "a kd requirement" if metric == KD else f"a requirement (torque_Nm and speed_rpm belong to metric = {KD!r})")
    has = [b for b in ("min", "max") if b in entry]
    if len(has) != 1:
        state = "both" if has else "neither"
        raise InputError(f"{where}: give exactly one of min or max, got {state}")
    bound = has[0]
    limit = _number(entry, bound, where)
    unit = _text(entry, "unit", where, required=True)
    quantity_of(unit, f"{where} unit")
    torque = speed = None
    if metric == KD:
        convert(1.0, unit, KD_UNIT, f"{where} unit")  # a stiffness unit
        torque = _range(entry, "torque_Nm", where, positive=True)
        speed = _range(entry, "speed_rpm", where, positive=False)
    default_name = f"{metric} {'>=' if bound == 'min' else '<='} {limit:g} {unit}"
    if metric == KD:
        default_name += f" over {torque[0]:g}-{torque[1]:g} Nm x {speed[0]:g}-{speed[1]:g} rpm"
    name = _text(entry, "name", where, default=default_name)
    return Requirement(name, metric, bound, limit, unit, torque, speed, where)


def _range(entry: dict, key: str, where: str, positive: bool) -> tuple[float, float]:
    """``[lo, hi]`` of finite numbers with lo ≤ hi (lo > 0 if ``positive``, else ≥ 0)."""
    if key not in entry:
        raise InputError(f"{where}: missing required key {key!r} (the operating region, [lo, hi])")
    value = entry[key]
    ok = (isinstance(value, list) and len(value) == 2
          and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value))
    if not ok or value[0] > value[1] or value[0] < 0 or (positive and value[0] == 0):
        low = "> 0" if positive else ">= 0"
        raise InputError(f"{where}: {key} must be [lo, hi] with {low} lo <= hi, got {value!r}")
    return float(value[0]), float(value[1])


def bind_requirements(spec: Spec, metric_specs, has_te_runs: bool) -> tuple[BoundRequirement, ...]:
    """Check every requirement against a campaign's metrics (``MetricSpec``s, e.g.
    ``derived_metrics_for(...).specs``) and convert its limit to the metric's unit."""
    columns = {s.name: (i, s.unit) for i, s in enumerate(metric_specs)}
    out = []
    for r in spec.requirements:
        if r.is_kd:
            if not has_te_runs:
                raise InputError(f"{r.where}: K_d over an operating region needs TE runs, and this "
                                 f"campaign has none")
            column, metric_unit = None, KD_UNIT
        elif r.metric in columns:
            column, metric_unit = columns[r.metric]
        else:
            raise InputError(f"{r.where}: unknown metric {r.metric!r}; this campaign's metrics are "
                             f"{', '.join(columns)} and {KD!r} (K_d over an operating region)")
        limit = convert(r.limit, r.unit, metric_unit, f"{r.where} unit (metric in {metric_unit})")
        out.append(BoundRequirement(r, column, limit, metric_unit))
    return tuple(out)
