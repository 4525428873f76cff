"""Temperature dependence across runs: compliance and friction level change with the run's
temperature (oil temperature of a TE bench, housing temperature of a hysteresis rig)."""

import equinox as eqx
import jax.numpy as jnp

from ._parameter import Parameter


class TemperatureDependence(eqx.Module):
    """At a run ``ΔT`` kelvin above the campaign's reference temperature, the compliance is
    scaled by ``exp(α_C·ΔT)`` and the friction level ``T_f`` by ``exp(α_f·ΔT)``.

    The load-dependent part of friction (μ|τ|) and the gap are left alone: warmer oil mostly
    lowers the no-load (churning, viscous) losses, while the mesh's load-dependent friction and
    its clearance hardly move over a bench's range. The exponentials keep both factors positive
    at any ΔT; for small ``α·ΔT`` they are ``1 + α·ΔT`` (α in 1/K, e.g. −0.02 = 2 % per kelvin).
    At the reference temperature (ΔT = 0) the model is the one without this term, so every
    derived metric is the value at the reference temperature.

    ``friction=False`` leaves the friction level alone: where the data cannot tell a softer
    spring from more friction (TE at one load per temperature: both widen the forward-backward
    span 2C(|τ| + T_f) the same way), α_C alone describes how the span changes.
    """

    friction: bool = eqx.field(static=True, default=True)

    def parameters(self) -> tuple[Parameter, ...]:
        out = (Parameter("temperature_compliance", "real", "1/K", "α_C: compliance scales by exp(α_C·ΔT)"),)
        if self.friction:
            out += (Parameter("temperature_friction", "real", "1/K", "α_f: friction level T_f scales by exp(α_f·ΔT)"),)
        return out

    def compliance_factor(self, params, temperature_delta_K):
        return jnp.exp(params["temperature_compliance"] * temperature_delta_K)

    def friction_params(self, params, temperature_delta_K) -> dict:
        """``params`` with the friction level at the run's temperature."""
        if not self.friction:
            return params
        scale = jnp.exp(params["temperature_friction"] * temperature_delta_K)
        return {**params, "friction_torque": params["friction_torque"] * scale}
