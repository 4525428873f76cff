"""Per draw: the quantity each requirement limits, and whether the draw conforms.

The same functions serve the posterior draws of a fit and a bench's true parameters (a batch of
one), so "is the truth in spec" is judged by exactly the rule the decision uses.
"""

import numpy as np

from .._x64 import in_float64
from ._envelope import region_kd_min


@in_float64
def requirement_quantities(bound, derived, values: dict, metric_draws=None) -> np.ndarray:
    """(draws, requirements): each requirement's quantity in its metric's unit — the metric, or
    for ``kd`` the smallest K_d over the region. ``bound``: ``BoundRequirement``s; ``derived``:
    the campaign's ``DerivedMetrics``; ``values``: stacked SI parameter draws; ``metric_draws``:
    the derived metrics of those draws (computed from ``values`` when None)."""
    if metric_draws is None and any(b.column is not None for b in bound):
        metric_draws = np.asarray(derived.over_draws(values))
    columns = []
    for b in bound:
        if b.column is None:
            r = b.requirement
            columns.append(region_kd_min(derived, values, r.torque_range_Nm, r.speed_range_rpm))
        else:
            columns.append(np.asarray(metric_draws)[:, b.column])
    return np.stack(columns, axis=1)


def conformance(bound, quantities: np.ndarray) -> np.ndarray:
    """(draws, requirements) bool: quantity ≥ limit for a ``min`` requirement, ≤ for a ``max``."""
    quantities = np.asarray(quantities, float)
    limits = np.array([b.limit_in_metric_unit for b in bound])
    is_min = np.array([b.requirement.bound == "min" for b in bound])
    return np.where(is_min, quantities >= limits, quantities <= limits)
