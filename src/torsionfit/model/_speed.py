"""Speed dependence in TE runs: viscous friction and speed-dependent compliance."""

import equinox as eqx
import jax.numpy as jnp

from ._parameter import Parameter


class SpeedDependence(eqx.Module):
    """``T_f(v) = T_f + c_v·|v|`` and compliance scaled by ``1 + s₁|v| + s₂v²``
    (v the output speed, rad/s). The paper's falling K_d: roughly linear for the large
    reducer, roughly parabolic for the small one (Figs. 16, 18)."""

    viscous: bool = eqx.field(static=True, default=True)
    compliance_order: int = eqx.field(static=True, default=1)  # 0, 1 or 2

    def parameters(self):
        out = ()
        if self.viscous:
            out += (Parameter("viscous_friction", "positive", "N·m·s/rad", "viscous friction c_v"),)
        if self.compliance_order >= 1:
            out += (Parameter("speed_compliance_1", "real", "s/rad", "compliance growth s₁ per |v|"),)
        if self.compliance_order >= 2:
            out += (Parameter("speed_compliance_2", "real", "s²/rad²", "compliance growth s₂ per v²"),)
        return out

    def friction_torque(self, params, friction_torque_Nm, speed_rad_s):
        if not self.viscous:
            return friction_torque_Nm
        return friction_torque_Nm + params["viscous_friction"] * jnp.abs(speed_rad_s)

    def compliance_factor(self, params, speed_rad_s):
        v = jnp.abs(speed_rad_s)
        f = 1.0
        if self.compliance_order >= 1:
            f = f + params["speed_compliance_1"] * v
        if self.compliance_order >= 2:
            f = f + params["speed_compliance_2"] * v**2
        return f
