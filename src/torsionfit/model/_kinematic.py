"""Kinematic error over output angle: harmonics at chosen integer orders."""

import equinox as eqx
import jax.numpy as jnp

from ._parameter import Parameter


class KinematicHarmonics(eqx.Module):
    """``θ_kin(φ) = Σ_k a_k cos kφ + b_k sin kφ`` over ``orders`` (per output revolution),
    e.g. 1, 2, the pin or tooth count, input-shaft orders R·j. Linear in a_k, b_k."""

    orders: tuple[int, ...] = eqx.field(static=True)

    def parameters(self):
        n = len(self.orders)
        return (
            Parameter("kin_cos", "real", "rad", "cosine amplitudes a_k", size=n, linear=True),
            Parameter("kin_sin", "real", "rad", "sine amplitudes b_k", size=n, linear=True),
        )

    def basis(self, output_angle_rad):
        """Design matrix (N, 2·n_orders): cos columns, then sin columns."""
        k = jnp.asarray(self.orders, dtype=float)
        phase = output_angle_rad[:, None] * k[None, :]
        return jnp.concatenate([jnp.cos(phase), jnp.sin(phase)], axis=1)

    def __call__(self, params, output_angle_rad):
        coef = jnp.concatenate([jnp.atleast_1d(params["kin_cos"]), jnp.atleast_1d(params["kin_sin"])])
        return self.basis(output_angle_rad) @ coef
