"""K_d over torque × speed from posterior draws: the worst case over an operating region (for a
``kd`` requirement) and the operating envelope P(K_d(τ, v) ≥ K_req) over a grid — the paper's
Fig. 19 made probabilistic.

K_d(τ, v) = τ / TE(180°) of the fitted model at load τ and output speed v, exactly as the
``kd_mean`` metrics (``DerivedMetrics.kd_over_draws``). A unit runs both ways, so K_d at a
condition is the smaller of the forward and backward values.
"""

from dataclasses import dataclass

import numpy as np

from .._x64 import in_float64

#: points per axis of the grid a ``kd`` requirement is checked on (corners included)
REGION_TORQUE_POINTS = 9
REGION_SPEED_POINTS = 5
#: points per axis of the envelope map
ENVELOPE_TORQUE_POINTS = 41
ENVELOPE_SPEED_POINTS = 31
#: the envelope's torque axis starts at this fraction of the rated torque (K_d → 0 at no load)
ENVELOPE_MIN_TORQUE_FRACTION = 0.1


@in_float64
def kd_worst_direction(derived, values: dict, torque_Nm, speed_rpm) -> np.ndarray:
    """min(K_d forward, K_d backward) (N·m/arcmin), (draws, conditions), at the paired 1-D
    ``torque_Nm`` and ``speed_rpm``; ``values`` are stacked SI parameter draws."""
    torque_Nm = np.asarray(torque_Nm, float)
    speed_rpm = np.asarray(speed_rpm, float)
    both_t, both_v = np.concatenate([torque_Nm, torque_Nm]), np.concatenate([speed_rpm, speed_rpm])
    direction = np.concatenate([np.ones_like(torque_Nm), -np.ones_like(torque_Nm)])
    kd = np.asarray(derived.kd_over_draws(values, both_t, both_v, direction))
    n = len(torque_Nm)
    return np.minimum(kd[:, :n], kd[:, n:])


def _mesh(torque_Nm, speed_rpm):
    """Flattened (torque, speed) pairs of the grid, speed-major: reshape to (speed, torque)."""
    t, v = np.meshgrid(np.asarray(torque_Nm, float), np.asarray(speed_rpm, float))
    return t.ravel(), v.ravel()


@in_float64
def region_kd_min(derived, values: dict, torque_range_Nm, speed_range_rpm) -> np.ndarray:
    """Per draw, the smallest K_d (N·m/arcmin) over the operating region: a grid of
    :data:`REGION_TORQUE_POINTS` × :data:`REGION_SPEED_POINTS` conditions, corners included,
    both directions."""
    t, v = _mesh(np.linspace(*torque_range_Nm, REGION_TORQUE_POINTS), np.linspace(*speed_range_rpm, REGION_SPEED_POINTS))
    return kd_worst_direction(derived, values, t, v).min(axis=1)


@dataclass(frozen=True)
class Envelope:
    """P(K_d(τ, v) ≥ ``k_req``) on a grid: ``probability[i, j]`` at ``speed_rpm[i]``,
    ``torque_Nm[j]``; ``k_req`` in ``unit``; ``region`` the requirement's (torque, speed) box."""

    requirement: str
    k_req: float
    unit: str
    p_accept: float
    torque_Nm: np.ndarray
    speed_rpm: np.ndarray
    probability: np.ndarray
    torque_range_Nm: tuple[float, float]
    speed_range_rpm: tuple[float, float]


def envelope_axes(rated_torque_Nm: float, max_speed_rpm: float, torque_range_Nm, speed_range_rpm):
    """Torque axis from 0.1·T_r (or lower, to include the region) to max(T_r, region), and speed
    axis from 0 to max(``max_speed_rpm``, region)."""
    t_lo = min(ENVELOPE_MIN_TORQUE_FRACTION * rated_torque_Nm, torque_range_Nm[0])
    t_hi = max(rated_torque_Nm, torque_range_Nm[1])
    v_hi = max(max_speed_rpm, speed_range_rpm[1], 1.0)
    return np.linspace(t_lo, t_hi, ENVELOPE_TORQUE_POINTS), np.linspace(0.0, v_hi, ENVELOPE_SPEED_POINTS)


@in_float64
def operating_envelope(derived, values: dict, bound, p_accept: float, torque_Nm, speed_rpm) -> Envelope:
    """The envelope of the ``kd`` requirement ``bound`` (a ``BoundRequirement``) over the grid
    ``torque_Nm`` × ``speed_rpm`` from stacked SI parameter draws ``values``."""
    r = bound.requirement
    t, v = _mesh(torque_Nm, speed_rpm)
    kd = kd_worst_direction(derived, values, t, v)
    prob = (kd >= bound.limit_in_metric_unit).mean(axis=0).reshape(len(speed_rpm), len(torque_Nm))
    return Envelope(r.name, r.limit, r.unit, p_accept, np.asarray(torque_Nm, float), np.asarray(speed_rpm, float),
                    prob, r.torque_range_Nm, r.speed_range_rpm)
