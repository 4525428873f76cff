"""Posterior sampling with NUTS (BlackJAX): a gradient-based sampler for the posteriors an
affine-invariant ensemble crosses too slowly (long, curved, funnel-shaped; DESIGN §2).

It samples the same density as emcee — ``problem.log_density(u)`` over the unconstrained
vector u, non-finite values mapped to −inf — and returns a :class:`NutsResult`, a
:class:`~torsionfit.sample.SampleResult` with NUTS's own statistics, so that
``report.finish_fit`` and ``sample.to_datatree`` treat both samplers alike.

Choices, and why:

- **Gradient**: exact, by JAX reverse mode through the model (the Dahl recurrence is a
  ``lax.scan``). Where the log-density is not finite its gradient is set to 0 (a custom VJP:
  one value-and-gradient pass, as BlackJAX's own), so a trajectory that leaves the support
  ends as a divergence, never with NaN coordinates.
- **Chains**: ``n_chains`` (4) independent chains, each its own compiled program, run on a
  pool of threads (one per core): a vmapped program cost more per chain than the chains one
  after the other (:func:`_per_chain`). Started from draws of the Laplace approximation taken
  in the sampler's own coordinates (z ~ N(0, I), below), each draw re-drawn until finite.
  Independent chains from dispersed starts are what R̂ needs (emcee's walkers are not
  independent).
- **Adaptation**: NUTS moves in coordinates centred at the mode of the density it samples and
  whitened by its curvature there (found from the MAP: :func:`_mode_and_curvature`; for the
  noise parameters, reshaped: :class:`Coordinates`), so the
  posterior is about N(0, I) there and the starting mass matrix is I. The curvature is taken
  by central differences of the exact gradient along the axes of the MAP's Laplace
  covariance, not that covariance itself: for a likelihood tempered for misfit
  (``fit/_misfit.py``) the Laplace covariance is widened for the physics only, and on
  data/paper-small (k ≈ 99) the noise levels were then ~√k wider than it said — the warm-up
  averaged ~460 leapfrog steps per draw against ~190 whitened by the curvature. BlackJAX's ``window_adaptation``
  (Stan's schedule: a fast window for the step size, doubling slow windows for the mass
  matrix, a final fast window) then adapts the step size and a **dense** mass matrix per
  chain, each window's estimate shrunk towards the previous one with a pseudo-count of
  :data:`SEED_PSEUDO_COUNT` draws; target acceptance 0.9 (Stan's 0.8 left one divergent
  transition in 2000 draws on the small SYNTHETIC bench campaign, seed 0 — the convergence
  rule then rejects the run; 0.9 left none on seeds 0 and 1, for ~35 % more leapfrog steps
  per draw).
- **Divergences**: a divergent transition after the warm-up means the step size was too large
  for the posterior's curvature somewhere. As Stan advises (raise ``adapt_delta``), the run then
  raises the target acceptance (1 − target halved, at most :data:`TARGET_ACCEPT_RAISES` times),
  adapts the chains again from where they are and discards the draws so far (they may be
  biased). On the measured baseline pos1 loop (an earlier model): 11 divergent transitions in 4 × 500 draws at
  0.9, none at 0.95 (46 leapfrog steps per draw). Divergences left at the last target fail
  the run.
- **Budget**: after the warm-up, draws in blocks; the chains are checked after
  ``initial_draws`` draws each and their length grown by half (at least a block) until converged or ``max_draws``.
  Every draw after the warm-up is kept (no thinning: NUTS draws are nearly independent).
- **Convergence** (the rule the fit reports): every entry of u has rank-normalised split R̂ ≤
  ``rhat_max`` (1.01), bulk and tail ESS ≥ ``min_ess`` (400), and no divergent transition
  after the warm-up. Divergences mean the sampler could not follow the posterior's
  curvature somewhere, so the draws may be biased there: the run is then reported not
  converged, whatever R̂ and ESS say. Monotone maps (u → SI values) leave rank-normalised R̂
  and ESS unchanged, so the rule on u is the rule on the physical parameters.
- **Resume**: with ``backend_path`` the state after every block (positions, step sizes, mass
  matrices, random key, draws so far) is written to a ``.npz`` file; ``resume=True``
  continues from it and gives the same draws as an uninterrupted run.
- ``tau`` of the result: the integrated autocorrelation time per entry of u, in draws,
  estimated as (chains · draws) / bulk ESS.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
import warnings
from dataclasses import dataclass
import functools
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._x64 import in_float64
from ..model import RUN_START_STATES
from ._convergence import chain_diagnostics, rhat_ess_shortfall
from ._emcee import ConvergenceWarning, SampleResult, _regularised_cov
from ._npz_file import save_npz_atomically

__all__ = ["NutsResult", "run_nuts"]

#: pseudo-count (draws) with which the first slow window keeps the Laplace covariance
SEED_PSEUDO_COUNT = 25.0
#: draws per compiled block after the warm-up (one compilation per problem shape)
BLOCK = 100
#: times the target acceptance is raised (1 − target halved: 0.9 → 0.95 → 0.975) and the chains
#: adapted again after divergent transitions, before the run is reported not converged
TARGET_ACCEPT_RAISES = 2


@dataclass(frozen=True, eq=False)
class NutsResult(SampleResult):
    """NUTS draws of u, laid out as emcee's (draws, chains, dim), with NUTS's statistics.

    ``diverging``, ``tree_depth``, ``n_leapfrog`` (draws, chains): divergent transition,
    number of trajectory doublings and leapfrog steps (= gradient evaluations) of each draw;
    ``acceptance_rate`` (draws, chains): mean Metropolis acceptance over the draw's
    trajectory. ``step_size`` (chains,), ``inverse_mass_matrix`` (chains, dim, dim): the
    adapted values. ``n_warmup`` warm-up steps per chain (``burn_in``); ``n_grad_evals``
    gradient evaluations over all chains, warm-up included. ``rhat``, ``ess_bulk``,
    ``ess_tail`` per entry of u.
    """

    diverging: np.ndarray | None = None
    tree_depth: np.ndarray | None = None
    n_leapfrog: np.ndarray | None = None
    step_size: np.ndarray | None = None
    inverse_mass_matrix: np.ndarray | None = None
    n_warmup: int = 0
    n_grad_evals: int = 0
    target_accept: float = 0.9
    rhat: np.ndarray | None = None
    ess_bulk: np.ndarray | None = None
    ess_tail: np.ndarray | None = None
    elapsed_s: float = 0.0
    preceded_by: dict | None = None  # auto: the emcee run before the switch (n_steps, n_walkers, ...)

    sampler = "nuts"

    @property
    def n_divergent(self) -> int:
        return int(np.sum(self.diverging)) if self.diverging is not None else 0


# --- the sampler's coordinates ---------------------------------------------------------------
class Coordinates(eqx.Module):
    """The coordinates w NUTS moves in, and their map to the problem's u (element-wise,
    monotone): the identity, except for the noise parameters of a :class:`FitProblem`.

    - excess noise s_r (u = log s_r; σ_r = √(s_r² + floor_r²)): s_r = c_r · softplus(w) with
      c_r = floor_r · (2 / N_r)^¼, the resolution of s at which the data see it (σ² is known
      to a relative 1/√(N/2), so s² to floor² · √(2/N)). Where s ≪ c the data hardly see s:
      in log s the posterior is the prior's tail on the left and an exponentially steep wall
      on the right (σ starts to grow) — a curvature no single step size follows (measured on
      the small test campaign: −290 per unit of log s at the wall, a Laplace sd of 0.6, and
      NUTS's adapted step fell to 0.01 with 360 leapfrog steps per draw). In w the left side
      stays log-like and the right side is linear in s, where the likelihood is smooth.
    - AR(1) coefficient ρ (u = logit ρ), for the same wall where ρ is near 0 (white noise):
      ρ = tanh(c_r · softplus(w)), c_r = 1/√N_r, the resolution of ρ.

    N_r is the run's sample count times the problem's likelihood power q (a likelihood raised
    to q < 1 for misfit sees N·q samples' worth: its resolutions are coarser).

    - gap β and friction level T_f of a campaign without hysteresis runs (TE only; its gap is
      :class:`~torsionfit.model.FrictionClosureBacklash`): in steady rotation both only shift TE by
      ±(β/2 + C·T_f) between the directions (C = 1/K the compliance), so the data see that sum
      and not its split — in (log β, log T_f) a curved ridge between the priors' tails
      (on the SYNTHETIC TE export campaign of the tests: hundreds of leapfrog steps per draw
      and chains that disagree). NUTS moves instead in w_a = log(β/2 + C·T_f) and w_b = log T_f − log β
      (C from the MAP's stiffness; a volume-preserving map, |du/dw| = 1), where the ridge is
      a straight line w_a = const.
      The share q of the gap closed at no load is seen, in the no-load runs, as the gap left
      open there, β(1 − q)/2 ≈ β·e^(−logit q)/2 for q near 1: its precision in logit q scales
      with 1/β, a funnel as β → 0 (on that campaign the one divergent transition of 2000 was
      at small β and q far below its posterior). NUTS moves in w_c = log β − logit q instead
      (the log of that open part; a shift, |du/dw| = 1).

    The log-density in w adds log |du/dw| (by JAX, element-wise).

    NUTS itself moves in z, w whitened by the Laplace approximation: w = w_MAP + L z, L the
    Cholesky factor of the Laplace covariance mapped to w (:meth:`whitened`; a constant
    Jacobian). The posterior is then about N(0, I), and so on the scale that the warm-up's
    regularisation of the mass matrix assumes (Stan's: a shrinkage towards 10⁻³ · I, which in
    u — where log stiffness has a posterior sd of 2·10⁻⁴ — inflated the stiffness variance a
    thousandfold: measured, a step size of 0.006 and 600 leapfrog steps per draw)."""

    noise: tuple = eqx.field(static=True)  # (first, end) indices of the noise levels in u
    ar1: tuple = eqx.field(static=True)  # (first, end) indices of the AR(1) logits
    log_noise_scale: jnp.ndarray  # log c_r per run
    ar1_scale: jnp.ndarray  # c_r per AR(1) run
    shift: jnp.ndarray | None = None  # w_MAP (None: z = w)
    chol: jnp.ndarray | None = None  # L
    #: (index of log β, of log T_f, of log K, of logit q) in u for the lost-motion coordinates, or ()
    lost_motion: tuple = eqx.field(static=True, default=())
    log_compliance: jnp.ndarray | None = None  # log C = −log K at the MAP (rad/N·m)
    #: u indices of the friction state before each hysteresis run's first sample (atanh z0),
    #: which :func:`_history_flips` reflects
    history: tuple = eqx.field(static=True, default=())

    @staticmethod
    def of(problem) -> "Coordinates":
        if not all(hasattr(problem, a) for a in ("floors", "n_nonlinear", "n_runs", "n_ar1", "y", "ar1")):
            return Coordinates((0, 0), (0, 0), jnp.zeros(0), jnp.zeros(0))
        n, r = int(problem.n_nonlinear), int(problem.n_runs)
        # a likelihood raised to the power q (widened for misfit) sees N·q samples' worth
        power = float(getattr(problem, "likelihood_power", 1.0))
        counts = np.array([len(y) for y in problem.y], dtype=float) * min(max(power, 1e-12), 1.0)
        floors = np.maximum(np.asarray(problem.floors, dtype=float), 1e-300)
        ar1_counts = counts[np.flatnonzero(np.asarray(problem.ar1, dtype=bool))]
        names = problem.names([""] * r) if hasattr(problem, "names") else []  # the problem's own layout of u
        history = tuple(i for i, name in enumerate(names) if name.split("[")[0] in RUN_START_STATES)
        return Coordinates((n, n + r), (n + r, n + r + int(problem.n_ar1)),
                           jnp.asarray(np.log(floors) + 0.25 * np.log(2.0 / counts)),
                           jnp.asarray(1.0 / np.sqrt(ar1_counts)), lost_motion=_lost_motion_pair(problem),
                           history=history)

    def whitened(self, u_map, cov_u, problem=None) -> "Coordinates":
        """These coordinates, whitened by N(u_map, cov_u) (cov regularised, mapped to w); with
        ``problem``, centred at the mode of its log-density in w and whitened by the curvature
        there (:func:`_mode_and_curvature`), which is what NUTS samples — e.g. a likelihood
        tempered for misfit, whose noise parameters are ~√k wider than the MAP's Laplace
        covariance says, and whose AR(1) coefficients the MAP holds at its cap."""
        self = self._with_compliance(u_map)
        w_map = self.from_u(jnp.asarray(u_map, dtype=float))
        jac = np.asarray(self.jacobian_diag(w_map))
        jac = np.where(np.isfinite(jac) & (np.abs(jac) > 0), jac, 1.0)
        cov_w = np.asarray(cov_u, dtype=float) / np.outer(jac, jac)
        if self.lost_motion:  # the pair's block: cov_w = J cov_u Jᵀ with J = dw/du
            j = np.eye(len(jac))
            idx = self._pair_indices()
            j[np.ix_(idx, idx)] = np.asarray(self._pair_dw_du(jnp.asarray(u_map)))
            cov_w = j @ cov_w @ j.T
        cov_w = _regularised_cov(cov_w)
        if problem is not None:
            w_map, cov_w, _ = _mode_and_curvature(problem, self, np.asarray(w_map), cov_w)
        return eqx.tree_at(lambda c: (c.shift, c.chol), self, (jnp.asarray(w_map), jnp.asarray(np.linalg.cholesky(cov_w))),
                           is_leaf=lambda x: x is None)

    @staticmethod
    def _noise_u(w, log_c):
        return log_c + jnp.log(jax.nn.softplus(w))

    @staticmethod
    def _ar1_u(w, c):
        x = c * jax.nn.softplus(w)
        # logit(tanh x) = log tanh x − log(1 − tanh x), both computed without cancellation
        log_tanh = jnp.log(-jnp.expm1(-2 * x)) - jnp.log1p(jnp.exp(-2 * x))
        log_one_minus = jnp.log(2.0) - jax.nn.softplus(2 * x)
        return log_tanh - log_one_minus

    @staticmethod
    def _softplus_inv(x):
        return x + jnp.log(-jnp.expm1(-x))

    def to_u(self, z):
        """(u, log |du/dz| summed, up to the constant of the whitening)."""
        w = z if self.chol is None else self.shift + self.chol @ z
        a, b = self.noise
        c, d = self.ar1
        u, logjac = w, 0.0
        if b > a:
            ws = w[a:b]
            u = u.at[a:b].set(jax.vmap(self._noise_u)(ws, self.log_noise_scale))
            logjac = logjac + jnp.sum(jnp.log(jnp.abs(jax.vmap(jax.grad(self._noise_u))(ws, self.log_noise_scale))))
        if d > c:
            wr = w[c:d]
            u = u.at[c:d].set(jax.vmap(self._ar1_u)(wr, self.ar1_scale))
            logjac = logjac + jnp.sum(jnp.log(jnp.abs(jax.vmap(jax.grad(self._ar1_u))(wr, self.ar1_scale))))
        if self.lost_motion:  # volume-preserving: no Jacobian term
            i_gap, i_fric, _, i_q = self.lost_motion
            log_gap = w[i_gap] - jnp.logaddexp(-jnp.log(2.0), w[i_fric] + self.log_compliance)
            u = u.at[i_gap].set(log_gap).at[i_fric].set(log_gap + w[i_fric])
            if i_q is not None:
                u = u.at[i_q].set(log_gap - w[i_q])
        return u, logjac

    def _with_compliance(self, u_map) -> "Coordinates":
        if not self.lost_motion:
            return self
        log_c = -jnp.asarray(np.asarray(u_map, dtype=float)[self.lost_motion[2]])
        return eqx.tree_at(lambda c: c.log_compliance, self, log_c, is_leaf=lambda x: x is None)

    def _pair_indices(self) -> list:
        """u indices of log β, log T_f and (when the gap has one) logit q: the entries the
        lost-motion map mixes."""
        i_gap, i_fric, _, i_q = self.lost_motion
        return [i_gap, i_fric] + ([] if i_q is None else [i_q])

    def _pair_w(self, log_gap, log_fric, logit_q=None):
        out = (jnp.logaddexp(log_gap - jnp.log(2.0), log_fric + self.log_compliance), log_fric - log_gap)
        return out if logit_q is None else out + (log_gap - logit_q,)

    def _pair_dw_du(self, u):
        """d(w_a, w_b[, w_c])/d(log β, log T_f[, logit q]) at ``u`` (2 × 2 or 3 × 3)."""
        return jax.jacfwd(lambda v: jnp.stack(self._pair_w(*v)))(u[jnp.asarray(self._pair_indices())])

    def from_u(self, u):
        """w of u (the inverse of :meth:`to_u`)."""
        a, b = self.noise
        c, d = self.ar1
        w = u
        if b > a:
            w = w.at[a:b].set(self._softplus_inv(jnp.exp(u[a:b] - self.log_noise_scale)))
        if d > c:
            rho = jax.nn.sigmoid(u[c:d])
            atanh = 0.5 * (jnp.log1p(rho) + jax.nn.softplus(u[c:d]))  # 1 − ρ = sigmoid(−u)
            w = w.at[c:d].set(self._softplus_inv(atanh / self.ar1_scale))
        if self.lost_motion:
            i_gap, i_fric, _, i_q = self.lost_motion
            pair = self._pair_w(*(u[i] for i in self._pair_indices()))
            w = w.at[i_gap].set(pair[0]).at[i_fric].set(pair[1])
            if i_q is not None:
                w = w.at[i_q].set(pair[2])
        if self.chol is None:
            return w
        return jax.scipy.linalg.solve_triangular(self.chol, w - self.shift, lower=True)

    def jacobian_diag(self, w):
        """du/dw per entry (1 outside the noise parameters) of the unwhitened coordinates; the
        lost-motion pair (not element-wise) counts as 1 here (:meth:`whitened` maps its block)."""
        plain = dataclasses.replace(self, shift=None, chol=None, lost_motion=())
        return jax.jvp(lambda v: plain.to_u(v)[0], (w,), (jnp.ones_like(w),))[1]


def _lost_motion_pair(problem) -> tuple:
    """(u index of the gap, of the friction level, of the stiffness, of the gap's closure or
    None) when ``problem``'s gap is :class:`~torsionfit.model.FrictionClosureBacklash` or
    :class:`~torsionfit.model.ClosedGapBacklash` (campaigns without hysteresis runs) and its
    compliance is one stiffness; else ()."""
    from ..model import ClosedGapBacklash, FrictionClosureBacklash

    model = getattr(problem, "model", None)
    if model is None or not isinstance(model.backlash, (FrictionClosureBacklash, ClosedGapBacklash)):
        return ()
    names = problem.names([""] * problem.n_runs)  # the problem's own layout of u
    keys = ("gap", "friction_torque", "stiffness") + (("gap_closure",) if "gap_closure" in names else ())
    if not all(k in names for k in keys):
        return ()
    return tuple(names.index(k) for k in keys) + ((None,) if len(keys) == 3 else ())


# --- the whitening: the mode and curvature of the density sampled --------------------------------
#: relative step of the central differences of the gradient (in coordinates whitened by the
#: Laplace covariance, where the posterior's scale is ~1)
CURVATURE_STEP = 1e-3
#: bounds on the eigenvalues of the curvature in those coordinates (variance 1e-4 … 1e4 of
#: the Laplace one); a direction of zero or negative curvature keeps the Laplace variance
CURVATURE_BOUNDS = (1e-4, 1e4)
#: at most this many Newton steps from the MAP towards the mode of the density sampled
MODE_NEWTON_STEPS = 30
#: a Newton step that gains less log density than this ends the search (within a fraction of
#: a posterior sd of the mode: close enough to centre the whitening)
MODE_TOLERANCE = 0.05


@eqx.filter_jit
def _values_and_grads(problem, coords, points):
    return jax.vmap(jax.value_and_grad(_log_density_fn(problem, coords)))(points)


def _local_quadratic(problem, plain, w, chol):
    """(log p(w), ∇ log p(w), −∇² log p(w) in the coordinates z of w + L z) from 2·dim + 1
    gradients: at w and at w ± h·L e_i (central differences along the axes of L = ``chol``).
    None where a value or gradient is not finite."""
    dim = chol.shape[0]
    h = CURVATURE_STEP
    steps = np.concatenate([np.zeros((1, dim)), np.eye(dim), -np.eye(dim)]) * h
    lp, g = (np.asarray(a) for a in _values_and_grads(problem, plain, jnp.asarray(w + steps @ chol.T)))
    g_z = g @ chol  # gradients in z (w = w_0 + L z)
    if not (np.all(np.isfinite(g_z)) and np.isfinite(lp[0])):
        return None
    hess = -(g_z[1:dim + 1] - g_z[dim + 1:]) / (2 * h)
    return float(lp[0]), g_z[0], 0.5 * (hess + hess.T)


def _bounded_inverse(hess_z):
    """The inverse of a curvature in whitened coordinates, its eigenvalues bounded by
    :data:`CURVATURE_BOUNDS` (a direction of zero or negative curvature keeps variance 1)."""
    lam, vec = np.linalg.eigh(hess_z)
    lo, hi = CURVATURE_BOUNDS
    lam = np.where(lam > 0, np.clip(lam, lo, hi), 1.0)
    return (vec / lam) @ vec.T


def _mode_and_curvature(problem, coords, w_map, cov_w):
    """(w at the mode of the density NUTS samples, the inverse of −∇² log p(w) there, gain in
    log density over ``w_map``), by damped Newton steps from the MAP whose curvature is the
    central difference of the exact gradient (:func:`_local_quadratic`; each step tries the
    Newton step and 2·dim of its halvings in one batch of the same compiled program).

    The MAP is not that mode when the density sampled is not the one the MAP maximised: the
    MAP re-estimates the AR(1) coefficients in closed form, capped at 0.995, and a likelihood
    tempered for misfit moves the noise levels' posterior. On data/paper-small (k ≈ 99) the
    mode lies 51 log-density units above the MAP, with ρ past the cap and noise levels two
    e-folds lower; whitened at the MAP, the chains ran 20 whitened units out along the noise
    levels during the warm-up and diverged. Falls back to ``w_map`` and its curvature where the
    differences are not finite, and to ``cov_w`` where even that fails."""
    plain = eqx.tree_at(lambda c: (c.shift, c.chol), coords, (None, None), is_leaf=lambda x: x is None)
    dim = len(w_map)
    w, chol = np.asarray(w_map, dtype=float), np.linalg.cholesky(cov_w)
    local = _local_quadratic(problem, plain, w, chol)
    if local is None:
        return w, cov_w, 0.0
    lp0 = lp = local[0]
    for _ in range(MODE_NEWTON_STEPS):
        _, g_z, hess_z = local
        cov_z = _bounded_inverse(hess_z)
        step = chol @ (cov_z @ g_z)
        lengths = 0.5 ** np.arange(2 * dim + 1)
        trial = w + lengths[:, None] * step
        values, _ = _values_and_grads(problem, plain, jnp.asarray(trial))
        values = np.where(np.isfinite(np.asarray(values)), np.asarray(values), -np.inf)
        best = int(np.argmax(values))
        if values[best] <= lp:
            break
        moved = _local_quadratic(problem, plain, trial[best], chol)
        if moved is None:
            break
        gain = values[best] - lp
        w, lp, local = trial[best], float(values[best]), moved
        if gain < MODE_TOLERANCE:
            break
    cov_z = _bounded_inverse(local[2])
    return w, chol @ cov_z @ chol.T, lp - lp0


# --- the log-density with a safe gradient --------------------------------------------------
def _finite_density(problem, coords, w):
    u, logjac = coords.to_u(w)
    lp = problem.log_density(u) + logjac
    return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)


@partial(jax.custom_vjp, nondiff_argnums=(0,))
def _safe_log_density(fn, u):
    return fn(u)


def _safe_fwd(fn, u):
    lp, g = jax.value_and_grad(fn)(u)
    ok = jnp.isfinite(lp) & jnp.all(jnp.isfinite(g))
    return jnp.where(ok, lp, -jnp.inf), jnp.where(ok, g, 0.0)


def _safe_bwd(fn, g, ct):
    return (ct * g,)


_safe_log_density.defvjp(_safe_fwd, _safe_bwd)


def _log_density_fn(problem, coords):
    """w → log-density (−inf off the support) with a gradient that is never NaN."""
    inner = partial(_finite_density, problem, coords)
    return lambda w: _safe_log_density(inner, w)


# --- compiled pieces (problem passed as an argument: its arrays are not baked into the program) --
def _bj():
    """BlackJAX, imported on first use: processes that never sample with NUTS never load it."""
    import blackjax

    return blackjax


@functools.lru_cache(maxsize=1)
def _info():
    return _bj().adaptation.base.get_filter_adapt_info_fn(
        info_keys={"acceptance_rate", "is_divergent", "num_integration_steps"})


@eqx.filter_jit
def _warmup_one(problem, coords, key, position, imm0, step0, num_steps: int, target_accept: float):
    """Window adaptation of one chain: (last state, step size, inverse mass matrix, leapfrog
    steps over the warm-up)."""
    adapt = _bj().window_adaptation(
        _bj().nuts, _log_density_fn(problem, coords), is_mass_matrix_diagonal=False, initial_inverse_mass_matrix=imm0,
        imm_shrinkage_to_previous=SEED_PSEUDO_COUNT, initial_step_size=step0,
        target_acceptance_rate=target_accept, adaptation_info_fn=_info())
    (state, params), info = adapt.run(key, position, num_steps)
    return state, params["step_size"], params["inverse_mass_matrix"], jnp.sum(info.info.num_integration_steps)


def _history_flips(logdensity, coords, key, state):
    """After a NUTS step, a Metropolis move per hysteresis run that reflects the friction state
    before its first sample, z0 → −z0 (u → −u): the unit was last loaded one way or the other
    before the file began, and a measured loop can fit both histories, separated by a valley at
    z0 ≈ 0 that NUTS's trajectories do not cross (on the measured baseline pos6 loop: modes at
    z0 ≈ −0.92 and +0.9; one chain of four switched once in 1000 draws, R̂ 1.12). The
    reflection is an involution of unit Jacobian in the sampler's coordinates, and the noise
    coordinates (the only ones with a log-Jacobian) are unchanged, so its acceptance is the
    ratio of the densities; a move costs one gradient (the state's, kept for NUTS)."""
    nuts = _bj().nuts
    for k, i in zip(jax.random.split(key, len(coords.history)), coords.history):
        u, _ = coords.to_u(state.position)
        flipped = nuts.init(coords.from_u(u.at[i].multiply(-1.0)), logdensity)
        take = jnp.log(jax.random.uniform(k)) < flipped.logdensity - state.logdensity
        state = jax.tree_util.tree_map(lambda a, b: jnp.where(take, a, b), flipped, state)
    return state


@eqx.filter_jit
def _sample_block_one(problem, coords, key, state, step_size, imm, n: int):
    """``n`` NUTS steps of one chain (scanned), each followed by :func:`_history_flips`."""
    logdensity = _log_density_fn(problem, coords)
    kernel = _bj().nuts(logdensity, step_size, imm)

    def step(state, key):
        key, k_flip = jax.random.split(key)
        new, info = kernel.step(key, state)
        if coords.history:
            new = _history_flips(logdensity, coords, k_flip, new)
        u, logjac = coords.to_u(new.position)
        out = (u, new.logdensity - logjac, info.is_divergent, info.num_trajectory_expansions,
               info.num_integration_steps, info.acceptance_rate)
        return new, out

    return jax.lax.scan(step, state, jax.random.split(key, n))


def _stack(trees):
    return jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *trees)


def _unstack(tree, n: int):
    return [jax.tree_util.tree_map(lambda x: x[i], tree) for i in range(n)]


def _per_chain(fn, n_chains: int, workers: int | None = None):
    """[fn(i) for i in range(n_chains)], the chains on a pool of threads (one per core, at most
    one per chain). Each chain is its own compiled program, not a lane of one vmapped program:
    a vmapped gradient through the model's scan over thousands of samples cost more per chain
    than the chains one after the other (data/paper-small, 4 chains: 11 ms against 4 × 2.2 ms),
    and XLA runs the calls of two threads on two cores at once."""
    workers = max(1, min(n_chains, workers or os.cpu_count() or 1))
    run = in_float64(fn)  # the float64 switch is thread-local
    if workers == 1:
        return [run(i) for i in range(n_chains)]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(workers) as pool:
        return list(pool.map(run, range(n_chains)))


def _warmup(problem, coords, keys, positions, imm0, step0, num_steps: int, target_accept: float):
    """Window adaptation per chain (:func:`_per_chain`): (last states stacked, step sizes,
    inverse mass matrices, leapfrog steps per chain over the warm-up)."""
    out = _per_chain(lambda i: _warmup_one(problem, coords, keys[i], positions[i], imm0, step0, num_steps,
                                           target_accept), len(positions))
    return tuple(_stack(x) for x in zip(*out))


def _sample_block(problem, coords, key, states, step_size, imm, n: int):
    """``n`` NUTS steps of every chain (:func:`_per_chain`; chain i draws with the key
    ``fold_in(key, i)``): (states stacked, outputs (steps, chains, …))."""
    n_chains = int(step_size.shape[0])
    each = _unstack(states, n_chains)
    out = _per_chain(lambda i: _sample_block_one(problem, coords, jax.random.fold_in(key, i), each[i], step_size[i],
                                                 imm[i], n), n_chains)
    new = _stack([o[0] for o in out])
    return new, tuple(jnp.stack(x, axis=1) for x in zip(*(o[1] for o in out)))


@eqx.filter_jit
def _densities(problem, coords, positions):
    return jax.vmap(partial(_finite_density, problem, coords))(positions)


def _initial_positions(problem, coords, n_chains: int, rng: np.random.Generator, max_rounds: int = 100) -> np.ndarray:
    """(n_chains, dim) starts z ~ N(0, I) — the Laplace approximation in the sampler's own
    coordinates, where a ridge that is curved in u is straight (a Gaussian draw in u along
    its tangent lands far off it: one chain of four then spent its whole warm-up at the
    deepest trees) — each re-drawn until its log-density is finite."""
    dim = int(problem.dim)
    z = np.zeros((n_chains, dim))
    todo = np.ones(n_chains, dtype=bool)
    for _ in range(max_rounds):
        z[todo] = rng.standard_normal((int(todo.sum()), dim))
        todo = ~np.isfinite(np.asarray(_densities(problem, coords, jnp.asarray(z))))
        if not todo.any():
            return z
    raise RuntimeError(f"{int(todo.sum())} of {n_chains} NUTS chains had a non-finite log-density in {max_rounds} "
                       "draws from the Laplace approximation; check the MAP fit")


@eqx.filter_jit
def _init_states(problem, coords, positions):
    return jax.vmap(lambda p: _bj().nuts.init(p, _log_density_fn(problem, coords)))(positions)


# --- diagnostics --------------------------------------------------------------------------------
def _check(rhat, bulk, tail, n_div, n_draws, rhat_max, min_ess, names) -> tuple[bool, str]:
    """(converged, reason): the rule of the module docstring; the reason names the worst entry."""
    if n_div:
        return False, (f"{n_div} divergent transitions after the warm-up (the sampler could not "
                       "follow the posterior's curvature; its draws may be biased)")
    reason = rhat_ess_shortfall(rhat, bulk, tail, n_draws, names, rhat_max, min_ess)
    return not reason, reason


def _no_draws(n_chains: int, dim: int) -> dict:
    return {k: np.zeros((0, n_chains) + s) for k, s in
            (("position", (dim,)), ("logdensity", ()), ("diverging", ()), ("depth", ()), ("leapfrog", ()),
             ("accept", ()))}


# --- resume file -----------------------------------------------------------------------------
def _load(path) -> dict | None:
    if not os.path.exists(path):
        return None
    with np.load(path, allow_pickle=False) as f:
        return {k: f[k] for k in f.files}


# --- the sampler ---------------------------------------------------------------------------
@in_float64
def run_nuts(problem, map_result, *, seed: int, n_chains: int = 4, n_warmup: int = 500,
             initial_draws: int = 200, max_draws: int = 4000, target_accept: float = 0.9,
             rhat_max: float = 1.01, min_ess: float = 400.0, backend_path=None, resume: bool = False,
             progress: bool = True) -> NutsResult:
    """Sample the posterior of ``problem`` with NUTS, started from ``map_result``'s Laplace
    approximation (``.u``, ``.cov``, ``.names``): ``n_chains`` chains, ``n_warmup`` adaptation
    steps each, then ``initial_draws`` draws per chain, grown by half until the convergence rule
    (module docstring) holds or ``max_draws`` is reached — then ``converged=False`` with the
    reason and a :class:`ConvergenceWarning`. ``backend_path``: a ``.npz`` file holding the
    state after every block; ``resume=True`` continues from it (same draws as a run without
    interruption; a file of another problem or other settings is an error)."""
    t0 = time.perf_counter()
    dim = int(problem.dim)
    names = tuple(getattr(map_result, "names", None) or (f"u[{i}]" for i in range(dim)))
    if n_chains < 2:
        raise ValueError("n_chains must be at least 2 (R̂ compares chains)")
    if initial_draws < BLOCK or max_draws < initial_draws:
        raise ValueError(f"need {BLOCK} ≤ initial_draws ≤ max_draws")
    say = (lambda text: print(f"[nuts] {text}", file=sys.stderr, flush=True)) if progress else (lambda text: None)
    settings = np.array([seed, n_chains, n_warmup, dim, target_accept], dtype=float)

    stored = _load(backend_path) if (backend_path is not None and resume) else None
    if stored is not None and not np.array_equal(stored["settings"], settings):
        raise ValueError(f"{backend_path}: the stored run has other settings or another problem "
                         f"(seed, chains, warm-up, dim, target: {stored['settings'].tolist()})")
    coords = Coordinates.of(problem).whitened(map_result.u, map_result.cov, problem)
    key = jax.random.PRNGKey(seed)
    k_warm, k_sample = jax.random.split(key)
    if stored is None:
        # whitened by the Laplace approximation, the first inverse mass matrix is I; NUTS's
        # step size for a well-preconditioned Gaussian in d dimensions is of order d^(-1/4)
        start_w = jnp.asarray(_initial_positions(problem, coords, n_chains, np.random.default_rng(seed)))
        say(f"warm-up: {n_chains} chains × {n_warmup} steps (dense mass matrix from the Laplace covariance)")
        states, step_size, imm, warm_leapfrog = _warmup(
            problem, coords, jax.random.split(k_warm, n_chains), start_w, jnp.eye(dim),
            float(dim) ** -0.25, int(n_warmup), float(target_accept))
        step_size, imm = np.asarray(step_size), np.asarray(imm)
        n_grad_warm = int(np.sum(warm_leapfrog))
        blocks = _no_draws(n_chains, dim)
        n_blocks_done, elapsed_before, target_now, raised = 0, 0.0, float(target_accept), []
    else:
        say(f"resuming {backend_path}: {stored['position'].shape[0]} draws per chain stored")
        step_size, imm = stored["step_size"], stored["imm"]
        n_grad_warm = int(stored["n_grad_warm"])
        # a NUTS state is the position with its log-density and gradient: recomputed exactly
        states = _init_states(problem, coords, jnp.asarray(stored["last"]))
        blocks = {k: stored[k] for k in ("position", "logdensity", "diverging", "depth", "leapfrog", "accept")}
        n_blocks_done, elapsed_before = int(stored["n_blocks"]), float(stored["elapsed_s"])
        target_now, raised = float(stored["target"]), [int(x) for x in stored["raised"]]

    def save():
        if backend_path is not None:
            save_npz_atomically(backend_path, settings=settings, step_size=step_size, imm=imm,
                                n_grad_warm=n_grad_warm, last=np.asarray(states.position), n_blocks=n_blocks_done,
                                elapsed_s=elapsed_before + time.perf_counter() - t0, target=target_now,
                                raised=np.asarray(raised, dtype=float), **blocks)

    if stored is None:
        save()  # an interruption in the first block keeps the warm-up

    target = initial_draws
    converged, reason = False, ""
    rhat = bulk = tail = np.full(dim, np.nan)
    while True:
        while blocks["position"].shape[0] < target:
            block_key = jax.random.fold_in(k_sample, n_blocks_done)
            states, out = _sample_block(problem, coords, block_key, states, jnp.asarray(step_size), jnp.asarray(imm), BLOCK)
            for name, arr in zip(("position", "logdensity", "diverging", "depth", "leapfrog", "accept"), out):
                blocks[name] = np.concatenate([blocks[name], np.asarray(arr, dtype=float)])
            n_blocks_done += 1
            save()
        n_draws = blocks["position"].shape[0]
        rhat, bulk, tail = chain_diagnostics(blocks["position"])
        n_div = int(np.sum(blocks["diverging"]))
        converged, reason = _check(rhat, bulk, tail, n_div, n_draws, rhat_max, min_ess, names)
        say(f"{n_draws} draws per chain: R̂ max {np.nanmax(rhat):.3f}, bulk ESS min {np.nanmin(bulk):.0f}, "
            f"tail ESS min {np.nanmin(tail):.0f}, {n_div} divergent, "
            f"{np.mean(blocks['leapfrog']):.1f} leapfrog steps per draw")
        if n_div and len(raised) < TARGET_ACCEPT_RAISES:
            # smaller steps where the curvature is high: adapt again, from where the chains
            # are, to a higher acceptance; the draws so far may be biased and are dropped
            raised.append(n_div)
            target_now = 1.0 - (1.0 - target_now) / 2
            say(f"{n_div} divergent transitions: adapting again to target acceptance {target_now:g}")
            n_grad_warm += int(np.sum(blocks["leapfrog"]))
            states, step_size, imm, warm_leapfrog = _warmup(
                problem, coords, jax.random.split(jax.random.fold_in(k_warm, len(raised)), n_chains),
                states.position, jnp.asarray(np.mean(imm, axis=0)), float(np.min(step_size)) / 2,
                int(n_warmup), float(target_now))
            step_size, imm = np.asarray(step_size), np.asarray(imm)
            n_grad_warm += int(np.sum(warm_leapfrog))
            blocks, target = _no_draws(n_chains, dim), initial_draws
            save()
            continue
        if converged or n_div or n_draws >= max_draws:
            break  # more draws do not remove divergences
        target = min(n_draws + max(BLOCK, n_draws // 2), max_draws)
    if not converged:
        reason = f"not converged after {n_draws} draws per chain (max_draws = {max_draws}): {reason}"
        warnings.warn(f"nuts: {reason}", ConvergenceWarning, stacklevel=3)  # 3: past the float64 wrapper

    n_warm_total = int(n_warmup) * (1 + len(raised))  # every adaptation, the dropped draws' not counted
    chain = blocks["position"]
    total = chain.shape[0] * chain.shape[1]
    tau = np.where(bulk > 0, total / np.where(bulk > 0, bulk, 1.0), np.inf)
    accept = blocks["accept"]
    bj = getattr(_bj(), "__version__", "?")
    return NutsResult(
        chain=chain, log_prob=blocks["logdensity"], tau=tau, n_steps=int(n_warm_total + chain.shape[0]),
        burn_in=int(n_warm_total), thin=1, acceptance_fraction=accept.mean(axis=0), converged=bool(converged),
        reason=reason, names=names, acceptance_rate=accept, seed=seed,
        moves=(f"NUTS (BlackJAX {bj}), {n_chains} chains, window adaptation of the step size and a dense "
               f"mass matrix seeded with the Laplace covariance, target acceptance {target_now:g}"
               + (f" (raised from {target_accept:g} and adapted again after "
                  f"{' then '.join(str(n) for n in raised)} divergent transitions; those draws dropped)"
                  if raised else "")),
        diverging=blocks["diverging"].astype(bool), tree_depth=blocks["depth"].astype(int),
        n_leapfrog=blocks["leapfrog"].astype(int), step_size=np.asarray(step_size), inverse_mass_matrix=np.asarray(imm),
        n_warmup=int(n_warm_total), n_grad_evals=int(n_grad_warm + np.sum(blocks["leapfrog"])),
        target_accept=float(target_now), rhat=rhat, ess_bulk=bulk, ess_tail=tail,
        elapsed_s=elapsed_before + time.perf_counter() - t0,
    )
