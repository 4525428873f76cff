"""Rate dependence: a viscoelastic creep element in series with the mesh."""

import equinox as eqx
import jax.numpy as jnp

from ._parameter import Parameter
from ._recurrence import ScanMethod, affine_scan


class Creep(eqx.Module):
    """``T_c·dθ_c/dt = τ_m/K_c − θ_c``, exact zero-order-hold update per sample:
    ``θ_c ← e·θ_c + (1 − e)·τ_m[n−1]/K_c`` with ``e = exp(−Δt/T_c)``.

    Starts in equilibrium with the first sample. Slow loading lets θ_c catch up (a larger
    angle at rated torque, a lower apparent stiffness); fast loading does not (paper Table 4).
    Duplicate time stamps (Δt = 0) leave θ_c unchanged, as they should.
    """

    def parameters(self):
        return (
            Parameter("creep_stiffness", "positive", "N·m/rad", "stiffness K_c of the creep element"),
            Parameter("creep_time", "positive", "s", "time constant T_c of the creep element"),
        )

    def twist(self, params, time_s, mesh_torque_Nm, method: ScanMethod = "auto"):
        """θ_c per sample (rad) for a time series of mesh torque."""
        target = mesh_torque_Nm / params["creep_stiffness"]
        e = jnp.exp(-jnp.diff(time_s) / params["creep_time"])
        theta = affine_scan(e, (1.0 - e) * target[:-1], target[0], method)
        return jnp.concatenate([target[:1], theta])

    def steady_twist(self, params, mesh_torque_Nm):
        """θ_c under a constant load held long enough (TE runs): τ_m/K_c."""
        return mesh_torque_Nm / params["creep_stiffness"]
