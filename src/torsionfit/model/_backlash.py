"""Geometric lost motion: the gap β is crossed while the mesh torque changes sign."""

import abc
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._parameter import Parameter
from ._play import play_scan
from ._recurrence import ScanMethod


class AbstractBacklash(eqx.Module):
    """Geometric lost motion θ_g (rad) as a function of the mesh torque (N·m)."""

    #: the gap's twist depends on the run's history (a state carried through the run), not on
    #: the mesh torque alone
    hysteretic = False

    @abc.abstractmethod
    def parameters(self) -> tuple[Parameter, ...]: ...

    @abc.abstractmethod
    def __call__(self, params, mesh_torque_Nm):
        """The gap's twist (rad) at each mesh torque, its history aside (a TE run's steady
        state, the geometric component at the applied torque)."""

    def run_twist(self, params, mesh_torque_Nm, method: ScanMethod = "auto", initial_state=None):
        """The gap's twist (rad) along one run's mesh torque sequence, its history carried
        (``initial_state``: the state at the first sample, for a hysteretic gap)."""
        return self(params, mesh_torque_Nm)


class SmoothBacklash(AbstractBacklash):
    """``θ_g = (β/2)·tanh(τ_m/τ_β)``: a gap β taken up over a mesh torque of about τ_β."""

    def parameters(self):
        return (
            Parameter("gap", "positive", "rad", "geometric gap β (lost motion of the mesh)"),
            Parameter("gap_torque", "positive", "N·m", "mesh torque τ_β over which the gap closes"),
        )

    def __call__(self, params, mesh_torque_Nm):
        return 0.5 * params["gap"] * jnp.tanh(mesh_torque_Nm / params["gap_torque"])


class FrictionClosureBacklash(AbstractBacklash):
    """``θ_g = (β/2)·tanh(atanh(q)·τ_m/T_f)``: :class:`SmoothBacklash` with its closing torque
    τ_β = T_f/atanh(q) given by q, the share of the gap closed at the sliding friction T_f
    (``friction_torque``) — the gap's state in a no-load TE run.

    The fitted backlash of campaigns without a hysteresis run. In steady rotation the mesh
    torque is the load plus the sliding friction and never passes through zero: loaded runs
    see the gap closed, no-load runs see q·β, and nothing sees τ_β itself. In τ_β the
    posterior is a curved ridge between "closed" and "wide gap, slowly closing" along which
    neither emcee nor NUTS converges in useful time; in q it is the prior where the data
    cannot resolve the no-load closure and a bump where they can."""

    def parameters(self):
        return (
            Parameter("gap", "positive", "rad", "geometric gap β (lost motion of the mesh)"),
            Parameter("gap_closure", "unit_interval", "1", "share q of the gap closed by the sliding friction alone"),
        )

    def __call__(self, params, mesh_torque_Nm):
        rate = jnp.arctanh(params["gap_closure"]) / params["friction_torque"]
        return 0.5 * params["gap"] * jnp.tanh(mesh_torque_Nm * rate)


class ClosedGapBacklash(AbstractBacklash):
    """``θ_g = (β/2)·sgn(τ_m)``: the gap closed, on the flank the mesh torque presses.

    The fitted backlash of campaigns whose every run is a loaded TE run. Their mesh torque is
    the load plus the sliding friction, far from zero, so the gap is closed in each and shows
    only in the lost motion between the directions; how it closes below the lightest load is
    seen by no run. :class:`FrictionClosureBacklash` there leaves the share q closed at no load
    to its prior, cut off where the lightest run would see the gap still opening — a wall whose
    place moves with the friction level, which NUTS crossed with dozens of divergent
    transitions (SYNTHETIC TE campaign at 100–380 N·m)."""

    def parameters(self):
        return (Parameter("gap", "positive", "rad", "geometric gap β (lost motion of the mesh)"),)

    def __call__(self, params, mesh_torque_Nm):
        return 0.5 * params["gap"] * jnp.sign(mesh_torque_Nm)


class PreloadedBacklash(AbstractBacklash):
    """A gap held closed by a preload, as in split-pinwheel (anti-backlash) designs: the two
    halves press on opposite flanks, so the mesh carries torque without lost motion until
    |τ_m| exceeds the preload T_p; beyond it one half lifts off and its half of the gap opens:

        ``θ_g = (β/4)·[tanh((τ_m − T_p)/τ_β) + tanh((τ_m + T_p)/τ_β)]``

    Each loading direction crosses β/2 near τ_m = ±T_p, so the two half-crossings of one branch
    sit 2·T_p apart in torque, and cycles within ±T_p of mesh torque (small play ramps) see no
    gap at all. T_p → 0 is :class:`SmoothBacklash`."""

    def parameters(self):
        return (
            Parameter("gap", "positive", "rad", "geometric gap β (lost motion of the mesh)"),
            Parameter("gap_torque", "positive", "N·m", "mesh torque τ_β over which each half of the gap closes"),
            Parameter("gap_preload_torque", "positive", "N·m", "preload T_p: mesh torque the gap stays closed below"),
        )

    def __call__(self, params, mesh_torque_Nm):
        w, tp = params["gap_torque"], params["gap_preload_torque"]
        return 0.25 * params["gap"] * (jnp.tanh((mesh_torque_Nm - tp) / w) + jnp.tanh((mesh_torque_Nm + tp) / w))


class ResidualPlayBacklash(AbstractBacklash):
    """A preloaded gap with a residual play: :class:`PreloadedBacklash` beside a small share w
    of the gap that the preload does not take up and that is crossed at zero mesh torque, over
    its own (sharper) torque τ₀:

        ``θ_g = (wβ/2)·tanh(τ_m/τ₀) + ((1 − w)β/4)·[tanh((τ_m − T_p)/τ_β) + tanh((τ_m + T_p)/τ_β)]``

    The measured preloaded split-pinwheel loops show both: their small play ramps (±4 N·m)
    cross a small gap in a jump near zero torque, their large ramps a wide one near the
    preload. β is the whole lost motion; w → 0 is :class:`PreloadedBacklash`."""

    def parameters(self):
        return PreloadedBacklash().parameters() + (
            Parameter("gap_residual_share", "unit_interval", "1", "share w of the gap the preload does not take up"),
            Parameter("gap_residual_torque", "positive", "N·m", "mesh torque τ₀ over which the residual play closes"),
        )

    def __call__(self, params, mesh_torque_Nm):
        w = params["gap_residual_share"]
        residual = 0.5 * w * params["gap"] * jnp.tanh(mesh_torque_Nm / params["gap_residual_torque"])
        return residual + (1.0 - w) * PreloadedBacklash()(params, mesh_torque_Nm)


#: steps of a stepped gap when it does not say: odd, so that one step sits at zero mesh torque.
#: With six (the Prandtl–Ishlinskii reference's gap columns) the steps sit at ±0.8, ±2.4 and
#: ±4 N·m of a ±4 N·m span, a single gap crossing at zero is not a case of the model, and on the
#: measured baseline loops whose crossing is centred the fit got worse in sample and out.
DEFAULT_GAP_STEPS = 7


class SteppedBacklash(AbstractBacklash):
    """A gap taken up in several steps, as by the pins of a printed pinwheel whose clearances
    differ: ``N`` smooth steps at mesh torques ``c_k`` spread evenly over ``±span_Nm``, each of
    width τ_β, sharing the gap β by weights ``w_k`` (a softmax of ``N − 1`` free logits, the
    first step's fixed at 0):

        ``θ_g = (β/2)·Σ_k w_k·tanh((τ_m − c_k)/τ_β)``

    Like :class:`SmoothBacklash` the twist runs from −β/2 to +β/2; the steps' positions are
    fixed by the construction, their shares fitted (the Prandtl–Ishlinskii reference's gap
    columns, with weights that sum to the gap)."""

    span_Nm: float = eqx.field(static=True)  # the unit's, not a number to guess: no default
    n_steps: int = eqx.field(static=True, default=DEFAULT_GAP_STEPS)

    def __check_init__(self):
        if not (isinstance(self.n_steps, int) and self.n_steps >= 2):
            raise ValueError(f"SteppedBacklash: n_steps must be an integer ≥ 2, got {self.n_steps!r}")
        if not self.span_Nm > 0:
            raise ValueError(f"SteppedBacklash: span_Nm must be positive, got {self.span_Nm!r}")

    def parameters(self):
        return (
            Parameter("gap", "positive", "rad", "geometric gap β (lost motion of the mesh)"),
            Parameter("gap_torque", "positive", "N·m", "mesh torque τ_β over which each step of the gap closes"),
            Parameter("gap_step_logits", "real", "1", "log shares of the gap's steps 2…N against the first",
                      size=self.n_steps - 1),
        )

    def centres_Nm(self):
        # exact and symmetric (linspace left the middle of an odd count at −1e−16 N·m)
        k = jnp.arange(self.n_steps)
        return self.span_Nm * (2 * k - (self.n_steps - 1)) / (self.n_steps - 1)

    @property
    def middle_step(self) -> int | None:
        """Index of the step at zero torque (an odd count), where every share is the plain
        centred gap; None for an even count, which has no such step."""
        return self.n_steps // 2 if self.n_steps % 2 == 1 else None

    def shares(self, params):
        logits = jnp.concatenate([jnp.zeros(1), jnp.atleast_1d(params["gap_step_logits"])])
        return jax.nn.softmax(logits)

    def __call__(self, params, mesh_torque_Nm):
        steps = jnp.tanh((mesh_torque_Nm[..., None] - self.centres_Nm()) / params["gap_torque"])
        return 0.5 * params["gap"] * steps @ self.shares(params)


class HeldGapBacklash(AbstractBacklash):
    """A gap held by its own friction: the flanks cross the gap only once the mesh torque
    exceeds a hold torque T_h, and then stay on their side until the torque exceeds T_h the
    other way — a relay, not a function of the torque. Split-pinwheel (anti-backlash) designs
    do this: their preloaded halves slide across the gap when the load overcomes the friction
    the preload holds them with, so a measured preloaded loop crosses its gap in one jump at a
    torque set by the preload (about ±12 N·m on the measured preload-3 units, whatever the
    peak), and small cycles within ±T_h (play ramps) never cross it.

    Smooth and exact per sample, the gap state g ∈ [−1, 1] is a play operator between two
    smooth gap curves:

        ``g ← clamp(g, tanh((τ_m − T_h)/τ_β), tanh((τ_m + T_h)/τ_β))``,  ``θ_g = (β/2)·g``

    T_h → 0 is :class:`SmoothBacklash`. Away from a run's history (a TE run's steady state, the
    geometric component at the applied torque) the gap is the smooth one; what holding it adds
    is hysteresis, booked as friction. ``initial_state`` g0 is the state at the first sample
    (0: the flanks midway in the gap), clamped to the band there.

    With ``centred = False`` the band is centred on a mesh torque c of its own
    (``gap_centre_torque``): the gap is crossed at c + T_h going up and c − T_h going down. Measured
    loops cross at torques whose centre lies off zero while their branches do not move with it
    (a torque offset would move both)."""

    hysteretic = True
    initial_state: float = eqx.field(static=True, default=0.0)
    centred: bool = eqx.field(static=True, default=True)

    def parameters(self):
        own_centre = () if self.centred else (
            Parameter("gap_centre_torque", "real", "N·m",
                      "mesh torque c the hold band is centred on: the gap crossed at c ± T_h"),)
        return SmoothBacklash().parameters() + (
            Parameter("gap_hold_torque", "positive", "N·m",
                      "hold torque T_h: mesh torque beyond which the flanks cross the gap", vanishes_at_zero=True),
        ) + own_centre

    def _relative(self, params, mesh_torque_Nm):
        return mesh_torque_Nm if self.centred else mesh_torque_Nm - params["gap_centre_torque"]

    def __call__(self, params, mesh_torque_Nm):
        return SmoothBacklash()(params, self._relative(params, mesh_torque_Nm))

    def band(self, params, mesh_torque_Nm):
        """(lower, upper) bound of the gap state g at each mesh torque."""
        w, th = params["gap_torque"], params["gap_hold_torque"]
        tau = self._relative(params, mesh_torque_Nm)
        return jnp.tanh((tau - th) / w), jnp.tanh((tau + th) / w)

    def state(self, params, mesh_torque_Nm, method: ScanMethod = "auto", initial_state=None):
        """Gap state g per sample, in [−1, 1] (−1: closed on the − flank, +1: on the + flank)."""
        lo, hi = self.band(params, jnp.asarray(mesh_torque_Nm))
        g0 = jnp.clip(jnp.asarray(self.initial_state if initial_state is None else initial_state, dtype=lo.dtype),
                      lo[0], hi[0])
        return jnp.concatenate([g0[None], play_scan(lo[1:], hi[1:], g0, method)])

    def run_twist(self, params, mesh_torque_Nm, method: ScanMethod = "auto", initial_state=None):
        return 0.5 * params["gap"] * self.state(params, mesh_torque_Nm, method, initial_state)


#: switches of a relay gap when it does not say: odd, so that one sits at the grid's centre and
#: the centred gap (the relay switching there both ways) is a case of the model
DEFAULT_GAP_THRESHOLDS = 7


#: the farthest a gap's relays may switch from their centre, as a share of the loops' largest
#: applied torque: a relay switching further switches in a loaded flank, where it draws the
#: hysteresis friction and compliance draw, not the gap's crossing (on measured split loops an
#: unbounded grid spread its switches over 0.8 of the peak and took a gap of 2140′ against the
#: data's 6.2′ play)
RELAY_FLANK_SHARE = 0.5


class RelayGapBacklash(AbstractBacklash):
    """A gap crossed in held steps (a Preisach gap): shares ``w_k`` of the gap β, each a relay
    that crosses its share once the mesh torque rises past its up-switch ``u_k`` and back once
    it falls past its down-switch ``d_k ≤ u_k``. The switches lie on a grid of ``n_thresholds``
    mesh torques spread evenly over ``c ± S`` (a centre c and a half-span S, both fitted); every
    pair ``u_k ≥ d_k`` of the grid is a relay (``d_k = u_k``: a step crossed at the same torque
    both ways). Each relay is :class:`HeldGapBacklash`'s smooth play operator, of width τ_β:

        ``g_k ← clamp(g_k, tanh((τ_m − u_k)/τ_β), tanh((τ_m − d_k)/τ_β))``,  ``θ_g = (β/2)·Σ_k w_k·g_k``

    with the shares a softmax of free logits (the first relay's fixed at 0). The measured
    baseline cycloidal loops cross their gap in a staircase whose steps sit at repeatable
    torques and differ between loading and unloading (several pins of a printed pinwheel, each
    held by its own friction); one held relay (:class:`HeldGapBacklash`) draws the largest step
    only. One relay ``(c + S·a, c − S·a)`` of the grid is :class:`HeldGapBacklash` centred on c
    and held S·a. ``initial_state`` g0 (or the run's
    start) is every relay's state at the first sample, clamped to its band there.
    ``max_span_Nm`` bounds S (N·m): the fit then takes S as a share of it
    (``gap_relay_span_share``), so that no relay switches further from c; unbounded by default."""

    hysteretic = True
    n_thresholds: int = eqx.field(static=True, default=DEFAULT_GAP_THRESHOLDS)
    initial_state: float = eqx.field(static=True, default=0.0)
    max_span_Nm: float | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if not (isinstance(self.n_thresholds, int) and self.n_thresholds >= 2):
            raise ValueError(f"RelayGapBacklash: n_thresholds must be an integer ≥ 2, got {self.n_thresholds!r}")
        if self.max_span_Nm is not None and not (isinstance(self.max_span_Nm, (int, float))
                                                 and math.isfinite(self.max_span_Nm) and self.max_span_Nm > 0):
            raise ValueError(f"RelayGapBacklash: max_span_Nm must be a finite torque > 0 N·m or None, got {self.max_span_Nm!r}")

    @property
    def n_relays(self) -> int:
        return self.n_thresholds * (self.n_thresholds + 1) // 2

    def parameters(self):
        return (
            Parameter("gap", "positive", "rad", "geometric gap β (lost motion of the mesh)"),
            Parameter("gap_torque", "positive", "N·m", "mesh torque τ_β over which each relay of the gap switches"),
            Parameter("gap_centre_torque", "real", "N·m", "mesh torque c the relays' switches are spread about"),
            Parameter("gap_relay_span", "positive", "N·m", "half-span S of the relays' switches about c")
            if self.max_span_Nm is None else
            Parameter("gap_relay_span_share", "unit_interval", "1",
                      "half-span S of the relays' switches about c, as a share of its bound max_span_Nm"),
            Parameter("gap_relay_logits", "real", "1", "log shares of the gap's relays 2…K against the first",
                      size=self.n_relays - 1),
        )

    def unit_switches(self) -> tuple[np.ndarray, np.ndarray]:
        """(up, down) switch of each relay on the grid over [−1, 1], in the order of the shares:
        by up-switch, then down-switch."""
        n = self.n_thresholds
        grid = (2 * np.arange(n) - (n - 1)) / (n - 1)
        up, down = zip(*[(grid[i], grid[j]) for i in range(n) for j in range(i + 1)])
        return np.array(up), np.array(down)

    def span_Nm(self, params):
        """The half-span S of the relays' switches (N·m)."""
        if self.max_span_Nm is None:
            return params["gap_relay_span"]
        return self.max_span_Nm * params["gap_relay_span_share"]

    def span_values(self, span_Nm: float) -> dict:
        """The parameter value that sets S to ``span_Nm`` (a start), within the bound's open
        interval when there is one: 99 % of it at most."""
        if self.max_span_Nm is None:
            return {"gap_relay_span": float(span_Nm)}
        return {"gap_relay_span_share": float(np.clip(span_Nm / self.max_span_Nm, 1e-3, 0.99))}

    def switches_Nm(self, params):
        """(up-switch u_k, down-switch d_k) of each relay (N·m of mesh torque)."""
        up, down = self.unit_switches()
        c, span = params["gap_centre_torque"], self.span_Nm(params)
        return c + span * up, c + span * down

    def nearest_relay(self, up: float, down: float) -> int:
        """Index of the relay whose switches on the unit grid lie nearest (up, down)."""
        grid_up, grid_down = self.unit_switches()
        return int(np.argmin((grid_up - up) ** 2 + (grid_down - down) ** 2))

    def shares(self, params):
        logits = jnp.concatenate([jnp.zeros(1), jnp.atleast_1d(params["gap_relay_logits"])])
        return jax.nn.softmax(logits)

    def logits_on(self, relay: int, share: float = 0.95) -> np.ndarray:
        """The free logits (``gap_relay_logits``) that put ``share`` of the gap on ``relay`` and
        the rest evenly on the others: a fit's start from one held relay (by default 95 % on it,
        the start of the fits and refits that extend a held gap)."""
        logits = np.zeros(self.n_relays)
        logits[relay] = np.log(share / (1.0 - share) * (self.n_relays - 1))
        return logits[1:] - logits[0]  # the first relay's logit is fixed at 0

    def __call__(self, params, mesh_torque_Nm):
        # history aside: each relay at the middle of its band
        up, down = self.switches_Nm(params)
        steps = jnp.tanh((mesh_torque_Nm[..., None] - 0.5 * (up + down)) / params["gap_torque"])
        return 0.5 * params["gap"] * steps @ self.shares(params)

    def band(self, params, mesh_torque_Nm):
        """(lower, upper) bound of each relay's state, shape (samples, relays)."""
        up, down = self.switches_Nm(params)
        tau = jnp.asarray(mesh_torque_Nm)[:, None]
        return jnp.tanh((tau - up) / params["gap_torque"]), jnp.tanh((tau - down) / params["gap_torque"])

    def state(self, params, mesh_torque_Nm, method: ScanMethod = "auto", initial_state=None):
        """Each relay's state per sample, shape (samples, relays), in [−1, 1]."""
        lo, hi = self.band(params, mesh_torque_Nm)
        g0 = jnp.clip(jnp.asarray(self.initial_state if initial_state is None else initial_state, dtype=lo.dtype),
                      lo[0], hi[0])
        return jnp.concatenate([g0[None], play_scan(lo[1:], hi[1:], g0, method)])

    def run_twist(self, params, mesh_torque_Nm, method: ScanMethod = "auto", initial_state=None):
        return 0.5 * params["gap"] * self.state(params, mesh_torque_Nm, method, initial_state) @ self.shares(params)


class NoBacklash(AbstractBacklash):
    """A gap-free mesh (θ_g = 0); for tests and gap-free designs."""

    def parameters(self):
        return ()

    def __call__(self, params, mesh_torque_Nm):
        return jnp.zeros_like(mesh_torque_Nm)
