"""Compliance ahead of the friction: a share of the elastic twist follows the applied torque.

The base model puts the whole compliance behind the friction: the spring sees the mesh torque
``τ_m = τ − T_fric``, so while friction sticks after a reversal the twist stays flat. Shafts,
couplings, bearings and a housing between the load and the friction contacts twist with the
applied torque at once. Measured loops of printed cycloidal reducers unload with a slope right
after each reversal instead of a flat plateau.
"""

import equinox as eqx

from ._parameter import Parameter


class SeriesCompliance(eqx.Module):
    """A share ``φ`` of the compliance curve sees the applied torque ``τ``, the rest the mesh
    torque: ``θ_e = φ·C(τ) + (1 − φ)·C(τ_m)`` (``φ = 0``: the base model). Right after a
    reversal, while friction holds, the twist moves with slope ``φ·C′(τ)``."""

    def parameters(self):
        return (Parameter("series_share", "unit_interval", "1",
                          "share φ of the compliance ahead of the friction (it sees the applied torque)",
                          vanishes_at_zero=True),)

    def twist(self, params, spring, torque_Nm, mesh_torque_Nm):
        """Elastic twist (rad); ``spring`` maps a torque (N·m) to the compliance curve's twist."""
        share = params["series_share"]
        return share * spring(torque_Nm) + (1.0 - share) * spring(mesh_torque_Nm)
