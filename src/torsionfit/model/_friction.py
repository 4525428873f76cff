"""Hysteretic friction between the applied torque and the gear mesh.

Every friction model maps the applied torque sequence to a friction torque sequence (N·m);
the mesh carries ``τ_m = τ − T_fric``. Two families:

- :class:`DahlFriction` (the base model): one smooth Dahl element of level ``T_f``;
- :class:`MaxwellSlipFriction` (``distributed_friction``): several Maxwell-slip elements —
  play operators on the torque — whose break-away levels follow a log-normal density around
  ``T_f``, so pre-sliding after a reversal is gradual, as measured loops show.

Either can make its level grow with the transmitted torque (``load_dependent_friction``):
gear friction scales with the normal load of the mesh, so after a reversal at a high peak the
twist stays flat over a much wider torque span than after a small one, and the loading and
unloading branches are not parallel. The load the level grows with is the instantaneous
|τ|, or |τ| through a first-order lag in time (``lag``), or a peak of |τ| the level remembers
while the torque travels back (``memory``): rate-independent amplitude memory, so the small
cycles of a play ramp slide at a level their own amplitude sets; or both (the lagged load's
peaks remembered).
"""

import abc
from statistics import NormalDist

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._parameter import Parameter
from ._play import play_scan
from ._recurrence import ScanMethod, affine_scan, first_order_lag, max_plus_scan

_LOAD = Parameter("friction_load_coefficient", "unit_interval", "1",
                  "μ: friction level grows by μ·|τ| with the transmitted torque")
_LOAD_LAG = Parameter("friction_load_lag_time", "positive", "s",
                      "time constant T_L of the load the friction level follows (|τ| through a first-order lag)",
                      vanishes_at_zero=True)
_LOAD_MEMORY = Parameter("friction_load_memory", "unit_interval", "1",
                         "m: after a peak the load the level grows with falls by (1 − m) per N·m the load travels "
                         "back, never below it (0: the load itself; 1: its largest value so far)",
                         vanishes_at_zero=True)


#: how a growing load raises Maxwell-slip elements' levels (:class:`MaxwellSlipFriction`)
LOAD_GROWTH = ("proportional", "common")


class AbstractFriction(eqx.Module):
    """Maps a torque sequence to a friction torque sequence (N·m)."""

    load_dependent: eqx.AbstractVar[bool]
    #: the level follows the load through a first-order lag in time (``load_dependent`` only)
    load_lag: eqx.AbstractVar[bool]
    #: the level remembers the last peak load while the torque travels back (``load_dependent`` only)
    load_memory: eqx.AbstractVar[bool]

    @abc.abstractmethod
    def parameters(self) -> tuple[Parameter, ...]: ...

    @abc.abstractmethod
    def friction_torque(self, params, torque_Nm, method: ScanMethod = "auto", initial_state=None, time_s=None): ...

    def _load_coefficient(self, params):
        return params["friction_load_coefficient"] if self.load_dependent else 0.0

    def _load_parameters(self) -> tuple[Parameter, ...]:
        if not self.load_dependent:
            return ()
        return (_LOAD,) + ((_LOAD_LAG,) if self.load_lag else ()) + ((_LOAD_MEMORY,) if self.load_memory else ())

    def level_load(self, params, torque_Nm, time_s=None, method: ScanMethod = "auto"):
        """The load (N·m) the friction level grows with, per sample: the transmitted torque's
        magnitude |τ|; with ``load_lag`` that magnitude through a first-order lag
        ``T_L·dL/dt = |τ| − L`` (needs ``time_s``; starting at |τ| at the first sample); with
        ``load_memory`` the peak of that load ℓ remembered while it falls,
        ``L[n] = max(ℓ[n], L[n−1] − (1 − m)·|Δℓ[n]|)`` (starting at ℓ at the first sample: the
        history before it is unknown). With both, the lagged load's peaks are remembered; m → 0
        is the lag alone, T_L → 0 the memory alone."""
        load = jnp.abs(jnp.asarray(torque_Nm))
        if not self.load_dependent:
            return load
        if self.load_lag:
            if time_s is None:
                raise ValueError("a friction level following the load with a lag needs the samples' times")
            load = first_order_lag(time_s, load, params["friction_load_lag_time"], method)
        if self.load_memory:
            # the peak falls with the load's own travel, not with time: the memory is rate-independent
            fall = (1.0 - params["friction_load_memory"]) * jnp.abs(jnp.diff(load))
            load = jnp.concatenate([load[:1], max_plus_scan(load[1:], -fall, load[0], method)])
        return load

    def sliding_level(self, params, torque_Nm):
        """Friction torque (N·m) while sliding steadily at torque ``torque_Nm`` (TE runs):
        ``T_f + μ·|τ|``."""
        return params["friction_torque"] + self._load_coefficient(params) * jnp.abs(torque_Nm)


class DahlFriction(AbstractFriction):
    """``dz = (|dτ|/τ_d)(sgn dτ − z)``; friction torque ``(T_f + μ|τ|)·z`` (μ = 0 unless
    ``load_dependent``).

    Exact one-sample update ``z ← a z + b``, ``a = exp(−|Δτ|/τ_d)``, ``b = sgn(Δτ)(1 − a)``.
    ``initial_state`` is z at the first sample (0: the unit starts at rest, unloaded).
    """

    initial_state: float = eqx.field(static=True, default=0.0)
    load_dependent: bool = eqx.field(static=True, default=False)
    load_lag: bool = eqx.field(static=True, default=False)
    load_memory: bool = eqx.field(static=True, default=False)

    def parameters(self):
        out = (
            Parameter("friction_torque", "positive", "N·m", "Coulomb friction level T_f"),
            Parameter("dahl_torque", "positive", "N·m", "torque change τ_d to saturate friction"),
        )
        return out + self._load_parameters()

    def state(self, params, torque_Nm, method: ScanMethod = "auto", initial_state=None):
        """Friction state z per sample (dimensionless, in (−1, 1)); ``initial_state``
        overrides the module's z at the first sample."""
        d_tau = jnp.diff(torque_Nm)
        a = jnp.exp(-jnp.abs(d_tau) / params["dahl_torque"])
        b = jnp.sign(d_tau) * (1.0 - a)
        z0 = jnp.asarray(self.initial_state if initial_state is None else initial_state, dtype=a.dtype)
        z = affine_scan(a, b, z0, method)
        return jnp.concatenate([z0[None], z])

    def friction_torque(self, params, torque_Nm, method: ScanMethod = "auto", initial_state=None, time_s=None):
        level = self.sliding_level(params, self.level_load(params, torque_Nm, time_s, method))
        return level * self.state(params, torque_Nm, method, initial_state)


class MaxwellSlipFriction(AbstractFriction):
    """``n_elements`` Maxwell-slip elements in parallel, each a play operator on the torque.

    Element k carries the mesh share ``p_k``; it sticks while ``|τ − p_k| ≤ R_k`` and slides
    at that limit otherwise (exact per sample: ``p_k ← clamp(p_k, τ − R_k, τ + R_k)``), with
    ``R_k = r_k·(1 + μ|τ|/T_f)`` (every level grows in proportion with the load; mean
    ``T_f + μ|τ|``). The break-away levels ``r_k = T_f·exp(s·q_k − s²/2)`` sit at the
    quantiles ``q_k`` of a standard normal: a log-normal break-away density of median
    ``T_f·e^(−s²/2)`` and mean ≈ ``T_f`` (the sliding friction level), spread ``s``. The
    friction torque is ``τ − mean_k p_k``. One element with s → 0 is ideal Coulomb friction.

    With ``load_growth = "common"`` the load adds one friction to every element instead,
    ``R_k = r_k + μ|τ|`` (same mean): the contacts' spread of break-away levels, in N·m, stays
    as the level grows, so pre-sliding is gradual after a small reversal and the knee sharp
    after a large one (the load's share sits on the loaded mesh, not on each contact's fit).

    ``initial_state`` z0 ∈ (−1, 1) places every element at ``p_k = τ_0 − z0·R_k`` at the first
    sample (0: at rest, no friction load).
    """

    n_elements: int = eqx.field(static=True, default=6)
    initial_state: float = eqx.field(static=True, default=0.0)
    load_dependent: bool = eqx.field(static=True, default=False)
    load_lag: bool = eqx.field(static=True, default=False)
    load_memory: bool = eqx.field(static=True, default=False)
    #: how the load raises the elements' levels: "proportional" (each by its share) or "common"
    load_growth: str = eqx.field(static=True, default="proportional")

    def __check_init__(self):
        if self.n_elements < 1:
            raise ValueError(f"n_elements must be ≥ 1, got {self.n_elements}")
        if self.load_growth not in LOAD_GROWTH:
            raise ValueError(f"load_growth must be one of {LOAD_GROWTH}, got {self.load_growth!r}")

    def parameters(self):
        out = (Parameter("friction_torque", "positive", "N·m", "sliding friction level T_f (mean break-away)"),)
        if self.n_elements > 1:
            out += (Parameter("breakaway_spread", "positive", "1", "log-sd s of the elements' break-away levels"),)
        return out + self._load_parameters()

    def _quantiles(self) -> np.ndarray:
        return np.array([NormalDist().inv_cdf((k + 0.5) / self.n_elements) for k in range(self.n_elements)])

    def breakaway_levels(self, params):
        """Break-away torque r_k of each element at zero load (N·m)."""
        if self.n_elements == 1:
            return jnp.atleast_1d(params["friction_torque"])
        s = params["breakaway_spread"]
        return params["friction_torque"] * jnp.exp(s * self._quantiles() - 0.5 * s**2)

    def mesh_shares(self, params, torque_Nm, method: ScanMethod = "auto", initial_state=None, time_s=None):
        """Each element's mesh share p_k per sample: (N, n_elements), N·m."""
        tau = jnp.asarray(torque_Nm)
        # every element's level grows in proportion with the load (each contact's friction
        # scales with its normal load), so the break-away spread — gradual pre-sliding — holds
        # at every load; the mean level is T_f + μ|τ|, as for Dahl friction
        load = self.level_load(params, tau, time_s, method)
        if self.load_growth == "common":
            limit = self.breakaway_levels(params)[None, :] + (self._load_coefficient(params) * load)[:, None]
        else:
            scale = 1.0 + self._load_coefficient(params) * load / params["friction_torque"]
            limit = self.breakaway_levels(params)[None, :] * scale[:, None]
        z0 = self.initial_state if initial_state is None else initial_state
        p0 = tau[0] - z0 * limit[0]
        p = play_scan(tau[1:, None] - limit[1:], tau[1:, None] + limit[1:], p0, method)
        return jnp.concatenate([p0[None, :], p], axis=0)

    def friction_torque(self, params, torque_Nm, method: ScanMethod = "auto", initial_state=None, time_s=None):
        return jnp.asarray(torque_Nm) - jnp.mean(self.mesh_shares(params, torque_Nm, method, initial_state, time_s), axis=1)
