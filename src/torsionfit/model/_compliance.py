"""Elastic compliance curves θ_e = C(τ_m): mesh torque (N·m) → twist (rad)."""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp

from ._parameter import Parameter


class AbstractCompliance(eqx.Module):
    """An odd, increasing map from mesh torque to elastic twist."""

    @abc.abstractmethod
    def parameters(self) -> tuple[Parameter, ...]: ...

    @abc.abstractmethod
    def __call__(self, params, torque_Nm): ...


class LinearCompliance(AbstractCompliance):
    """``θ = τ / K``."""

    def parameters(self):
        return (Parameter("stiffness", "positive", "N·m/rad", "elastic stiffness K"),)

    def __call__(self, params, torque_Nm):
        return torque_Nm / params["stiffness"]


def _smooth_ramp(x, width):
    """``width·softplus(x/width)``: max(x, 0) with a knee of about ``width``."""
    return width * jax.nn.softplus(x / width)


class ThreeSegmentCompliance(AbstractCompliance):
    """Catalog curve: stiffness K1 below T1, K2 from T1 to T2, K3 above; smooth knees.

    Odd in τ. Each knee is a softplus blend ``knee_fraction·T_i`` wide.
    """

    knee_fraction: float = eqx.field(static=True, default=0.1)

    def parameters(self):
        return (
            Parameter("k1", "positive", "N·m/rad", "stiffness below T1"),
            Parameter("k2", "positive", "N·m/rad", "stiffness between T1 and T2"),
            Parameter("k3", "positive", "N·m/rad", "stiffness above T2"),
            Parameter("t1", "positive", "N·m", "first knee torque T1"),
            Parameter("t2_minus_t1", "positive", "N·m", "T2 − T1 (keeps T2 > T1)"),
        )

    def __call__(self, params, torque_Nm):
        k1, k2, k3 = params["k1"], params["k2"], params["k3"]
        t1 = params["t1"]
        t2 = t1 + params["t2_minus_t1"]
        w1, w2 = self.knee_fraction * t1, self.knee_fraction * t2

        def knee(t, w):  # odd: ramps above +t and below −t
            return _smooth_ramp(torque_Nm - t, w) - _smooth_ramp(-torque_Nm - t, w)

        return torque_Nm / k1 + (1 / k2 - 1 / k1) * knee(t1, w1) + (1 / k3 - 1 / k2) * knee(t2, w2)


class PowerLawCompliance(AbstractCompliance):
    """``θ = sgn(τ)·θ_r·(|τ|/τ_r)^(1/p)``: p > 1 stiffens with load; θ_r is the elastic twist
    (rad) at the reference torque τ_r (N·m, the rated torque in a fit).

    The twist at the reference torque, not the torque that twists 1 rad (``c`` in
    ``(|τ|/c)^(1/p)``), is the parameter because it is what a loop pins down: with c, every
    change of p must be paid for by a change of log c of about −log θ at the loop's torques,
    a curved ridge (log c and log p 0.99 correlated at a measured loop's MAP, the exponent the
    slowest coordinate of a sampler there); log θ_r and log p are 0.29 correlated on that loop.

    |τ| is smoothed over ``smoothing_Nm`` so the curve and its gradients stay finite at 0.
    """

    reference_torque_Nm: float = eqx.field(static=True)
    smoothing_Nm: float = eqx.field(static=True, default=1e-3)

    def __check_init__(self):
        if not self.reference_torque_Nm > 0:
            raise ValueError(f"PowerLawCompliance: reference_torque_Nm must be > 0, got {self.reference_torque_Nm!r}")

    def parameters(self):
        return (
            Parameter("elastic_rated_twist", "positive", "rad", "elastic twist θ_r at the reference (rated) torque"),
            Parameter("power_exponent", "positive", "1", "exponent p"),
        )

    def __call__(self, params, torque_Nm):
        eps = self.smoothing_Nm
        mag = jnp.sqrt(torque_Nm**2 + eps**2) - eps
        shape = (mag / self.reference_torque_Nm + 1e-300) ** (1.0 / params["power_exponent"])
        return jnp.sign(torque_Nm) * params["elastic_rated_twist"] * shape


class AsymmetricCompliance(AbstractCompliance):
    """Different compliance for + and − torque: ``θ = C(τ)·(1 + α·tanh(τ/w))``.

    α = 0 is the symmetric curve; compliance is (1+α)× for τ ≫ w and (1−α)× for τ ≪ −w.
    """

    base: AbstractCompliance
    switch_width_Nm: float = eqx.field(static=True, default=1.0)

    def parameters(self):
        return self.base.parameters() + (
            Parameter("compliance_asymmetry", "real", "1", "α: relative +/− compliance difference"),
        )

    def __call__(self, params, torque_Nm):
        alpha = params["compliance_asymmetry"]
        return self.base(params, torque_Nm) * (1.0 + alpha * jnp.tanh(torque_Nm / self.switch_width_Nm))


class PreloadedCompliance(AbstractCompliance):
    """A second load path held closed by a preload, as in split-pinwheel (anti-backlash)
    designs: below the lift-off torque T_s both preloaded halves carry the load in parallel and
    the unit is stiffer; beyond it one half lifts off and the base curve's slope returns:

        ``θ = C(τ) − s·C(clip(τ, −T_s, T_s))``

    Inside ±T_s the compliance is (1 − s)·C (a parallel path of r·K on a spring K gives
    s = r/(1 + r)); beyond, the base slope C′(τ), the twist continuous at ±T_s. Odd and
    increasing for 0 ≤ s < 1; s = 0 is the base curve. Unlike :class:`PreloadedBacklash`,
    which holds the *gap* closed below a preload, this changes the *spring*."""

    base: AbstractCompliance

    def parameters(self):
        return self.base.parameters() + (
            Parameter("preload_stiffening", "unit_interval", "1",
                      "share s of the compliance the preloaded second path takes away below the lift-off torque",
                      vanishes_at_zero=True),
            Parameter("preload_lift_torque", "positive", "N·m", "torque T_s beyond which the preloaded path lifts off"),
        )

    def __call__(self, params, torque_Nm):
        lift = params["preload_lift_torque"]
        inside = jnp.clip(torque_Nm, -lift, lift)
        return self.base(params, torque_Nm) - params["preload_stiffening"] * self.base(params, inside)
