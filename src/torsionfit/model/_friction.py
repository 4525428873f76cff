"""Hysteretic friction: a Dahl-type state z ∈ (−1, 1) driven by torque increments."""

import abc

import equinox as eqx
import jax.numpy as jnp

from ._parameter import Parameter
from ._recurrence import ScanMethod, affine_scan


class AbstractFriction(eqx.Module):
    """Maps a torque sequence to a friction torque sequence (N·m)."""

    @abc.abstractmethod
    def parameters(self) -> tuple[Parameter, ...]: ...

    @abc.abstractmethod
    def friction_torque(self, params, torque_Nm, method: ScanMethod = "auto", initial_state=None): ...


class DahlFriction(AbstractFriction):
    """``dz = (|dτ|/τ_d)(sgn dτ − z)``; friction torque ``T_f·z``.

    Exact one-sample update ``z ← a z + b``, ``a = exp(−|Δτ|/τ_d)``, ``b = sgn(Δτ)(1 − a)``.
    ``initial_state`` is z at the first sample (0: the unit starts at rest, unloaded).
    """

    initial_state: float = eqx.field(static=True, default=0.0)

    def parameters(self):
        return (
            Parameter("friction_torque", "positive", "N·m", "Coulomb friction level T_f"),
            Parameter("dahl_torque", "positive", "N·m", "torque change τ_d to saturate friction"),
        )

    def state(self, params, torque_Nm, method: ScanMethod = "auto", initial_state=None):
        """Friction state z per sample (dimensionless, in (−1, 1)); ``initial_state``
        overrides the module's z at the first sample."""
        d_tau = jnp.diff(torque_Nm)
        a = jnp.exp(-jnp.abs(d_tau) / params["dahl_torque"])
        b = jnp.sign(d_tau) * (1.0 - a)
        z0 = jnp.asarray(self.initial_state if initial_state is None else initial_state, dtype=a.dtype)
        z = affine_scan(a, b, z0, method)
        return jnp.concatenate([z0[None], z])

    def friction_torque(self, params, torque_Nm, method: ScanMethod = "auto", initial_state=None):
        return params["friction_torque"] * self.state(params, torque_Nm, method, initial_state)
