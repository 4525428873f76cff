"""Bijections between constrained parameters and the unconstrained space the fit works in.

Each maps u ∈ ℝ to a value; ``log_jacobian(u) = log|d value / d u|`` enters the log-density
so that priors written on the natural scale stay correct in the sampled space.
"""

import jax
import jax.numpy as jnp


def forward(constraint: str, u):
    if constraint == "positive":
        return jnp.exp(u)
    if constraint == "unit_interval":
        return jax.nn.sigmoid(u)
    if constraint == "signed_unit":
        return jnp.tanh(u)
    if constraint == "real":
        return u
    raise ValueError(f"unknown constraint {constraint!r}")


def inverse(constraint: str, value):
    value = jnp.asarray(value, float)
    if constraint == "positive":
        return jnp.log(value)
    if constraint == "unit_interval":
        return jnp.log(value) - jnp.log1p(-value)
    if constraint == "signed_unit":
        return jnp.arctanh(value)
    if constraint == "real":
        return value
    raise ValueError(f"unknown constraint {constraint!r}")


def log_jacobian(constraint: str, u):
    if constraint == "positive":
        return u
    if constraint == "unit_interval":
        return jax.nn.log_sigmoid(u) + jax.nn.log_sigmoid(-u)
    if constraint == "signed_unit":
        return jnp.log1p(-jnp.tanh(u) ** 2)
    if constraint == "real":
        return jnp.zeros_like(u)
    raise ValueError(f"unknown constraint {constraint!r}")
