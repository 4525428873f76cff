"""A damped gap crossing: the gap follows the mesh torque through a first-order lag.

Crossing the gap, nothing but damping holds the free side back, so the crossing trails the
torque in time, while the loaded flanks (stiff) follow at once. Measured loops of printed
cycloidal reducers show exactly that: at the torque peaks the twist turns with the torque
(within one sample), but across the gap it runs late — a first-order lag of 0.2–0.5 s on the
gap columns alone lowers the Prandtl–Ishlinskii reference's held-out error as much as a lag of
the whole torque does. The geometric twist is evaluated at ``τ_g``,
``T_g·dτ_g/dt = τ_m − τ_g``; what that changes is rate-dependent (the ``creep`` component).
"""

import equinox as eqx

from ._parameter import Parameter
from ._recurrence import ScanMethod, first_order_lag


class GapLag(eqx.Module):
    """First-order lag ``T_g`` (s) of the torque the gap sees behind the mesh torque (exact per
    sample for a torque linear between samples; ``T_g → 0`` is the undamped gap)."""

    def parameters(self):
        return (Parameter("gap_lag_time", "positive", "s", "time constant T_g of the damped gap crossing",
                          vanishes_at_zero=True),)

    def gap_torque(self, params, time_s, mesh_torque_Nm, method: ScanMethod = "auto"):
        """Torque (N·m) at which the gap is evaluated, per sample."""
        return first_order_lag(time_s, mesh_torque_Nm, params["gap_lag_time"], method)
