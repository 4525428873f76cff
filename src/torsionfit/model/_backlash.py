"""Geometric lost motion: the gap β is crossed while the mesh torque changes sign."""

import abc

import equinox as eqx
import jax.numpy as jnp

from ._parameter import Parameter


class AbstractBacklash(eqx.Module):
    @abc.abstractmethod
    def parameters(self) -> tuple[Parameter, ...]: ...

    @abc.abstractmethod
    def __call__(self, params, mesh_torque_Nm): ...


class SmoothBacklash(AbstractBacklash):
    """``θ_g = (β/2)·tanh(τ_m/τ_β)``: a gap β taken up over a mesh torque of about τ_β."""

    def parameters(self):
        return (
            Parameter("gap", "positive", "rad", "geometric gap β (lost motion of the mesh)"),
            Parameter("gap_torque", "positive", "N·m", "mesh torque τ_β over which the gap closes"),
        )

    def __call__(self, params, mesh_torque_Nm):
        return 0.5 * params["gap"] * jnp.tanh(mesh_torque_Nm / params["gap_torque"])


class NoBacklash(AbstractBacklash):
    """A gap-free mesh (θ_g = 0); for tests and gap-free designs."""

    def parameters(self):
        return ()

    def __call__(self, params, mesh_torque_Nm):
        return jnp.zeros_like(mesh_torque_Nm)
