"""Posterior sampling with emcee (DESIGN §2): an affine-invariant ensemble over the
unconstrained vector u of a :class:`~torsionfit.fit.FitProblem`.

Choices, and why:

- **Log-density**: ``problem.log_density`` vmapped over walkers and jitted once per problem
  *shape* (module-level, with the MAP's XLA options: ``fit/_map.py``), handed to emcee with
  ``vectorize=True``: one call evaluates half the ensemble (emcee's red–blue split), so the
  compiled batch sizes are ``n_walkers`` (first call) and ``n_walkers / 2``. NumPy in, NumPy
  out; any non-finite value (NaN, ±inf, from absurd u) becomes −inf, which emcee rejects.
- **Moves**: a mixture of ``LaplaceMove`` (0.5), ``DEMove`` (0.4) and ``StretchMove`` (0.1).
  ``LaplaceMove`` (``_laplace_move.py``) is an independence Metropolis–Hastings proposal from
  a Student-t around the MAP with the Laplace covariance: valid whatever the approximation's
  quality, and where it is good a walker crosses the posterior in one step. The
  differential-evolution move (ter Braak 2006) proposes along the difference of two other
  walkers and the stretch move is emcee's affine-invariant default: they carry the sampling
  where the Laplace approximation is poor. Measured τ_max: on the 14-parameter test campaign
  (32 walkers, 8000 steps, two seeds) ≈ 195 steps with the stretch move alone, ≈ 70 with
  DE 0.8 + stretch 0.2, ≈ 63 with DE alone; on ``benchmarks/benches/full_fit_2k.toml``
  (3000 steps, ``benchmarks/bench_moves.py``) 43.7 with DE 0.8 + stretch 0.2, 6.2 with this
  mixture, 3.9 with Laplace 0.8 + DE 0.2 — the ensemble moves keep half the weight as insurance for posteriors far from
  Gaussian. Where the Laplace proposals are almost never accepted (a loop the model misses),
  their half of the steps would be wasted: at the first check the move is retired when fewer
  than 5 % were accepted, its share going to DE (``SampleResult.moves`` says so; measured
  initial-pos1: acceptance 0.4 %, τ_max 981 steps with the Laplace move kept, 642 retired).
- **Walkers**: ``max(32, 2·dim + 2)`` rounded up to even (emcee needs an even ensemble for
  the red–blue split and at least 2·dim walkers). Started from the Laplace approximation
  N(MAP, cov) of ``fit_map`` — cov regularised in correlation form so that the ensemble is
  never degenerate — each draw re-drawn until its log-density is finite.
- **Stopping** (emcee's documented recipe): run in blocks of ``check_every`` steps; after
  each block estimate the integrated autocorrelation time τ per parameter
  (``get_autocorr_time(tol=0)``); stop when the chain is longer than ``tau_factor · max τ``
  (50 by default, DESIGN §2), max τ changed by less than ``tau_rtol`` (1 %) since the
  previous check, and at least ``min_steps`` steps were made. emcee's tutorial asks every
  τ to be stable to 1 %; with 500-step blocks and a dozen parameters the estimates' noise
  (the adaptive window jumps) keeps some τ moving by 1–4 % long after max τ has settled —
  on the 14-parameter test campaign (with a stretch-dominant mix) that rule was not met in
  20 000 steps (138 τ), while max τ was stable at 10 000. Max τ is what the length rule and
  the burn-in use, so its stability is what the stopping rule needs. With short τ the estimate
  itself scatters by a few % from check to check (τ ≈ 6.4: 6.5, 6.8, 6.7, 6.3, 6.4 at 500-step
  checks) and the 1 % rule then waits on noise; so the stability test is waived once the chain
  is longer than twice the required length (2 · ``tau_factor`` · both estimates): an error of
  τ under 2× cannot make such a chain too short. Then the rule every sampler is judged by
  (``_convergence``: R̂ ≤ 1.01, bulk and tail ESS ≥ 400 for every entry of u, the kept draws
  with walkers as chains): a chain 50 τ long can still fail it (the small paper-test campaign:
  R̂ 1.015 at the τ rule's stop), and then it runs on. Reaching ``max_steps`` first gives
  ``converged=False`` and a :class:`ConvergenceWarning` naming the shortfall.
- **Burn-in / thinning**: burn-in = ⌈2 · max τ⌉ steps, thinning = max(1, ⌊min τ / 2⌋) — the
  values emcee's documentation uses. Both are capped so that at least half of the chain and
  at least 2 draws per walker remain, even for an unconverged chain.
- **Backend**: optional HDF5 file in emcee's ``HDFBackend`` layout, written in blocks by
  :class:`BufferedHDFBackend` (emcee's own backend opens the file for every step, which
  costs more than the log-density), with the random state. ``resume=True`` continues from
  the backend's last stored step with its stored random state, so an interrupted and
  resumed run gives the same chain as an uninterrupted one.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import warnings
from dataclasses import dataclass, field

import emcee
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from .._x64 import in_float64
from .._chunks import map_chunks
from ..fit._map import _map_compiler_options, _map_jit
from ._convergence import chain_diagnostics, rhat_ess_shortfall
from ._laplace_move import RETIRE_BELOW, LaplaceMove

#: progress lines (INFO); the command line shows them on stderr unless --quiet
log = logging.getLogger(__name__)

__all__ = ["BufferedHDFBackend", "ConvergenceWarning", "SampleResult", "batch_log_density",
           "default_n_walkers", "initial_walkers", "run_sampler"]

#: the move mixture handed to emcee (weights sum to 1)
MOVES_DESCRIPTION = "LaplaceMove (0.5) + DEMove (0.4) + StretchMove (0.1)"


class ConvergenceWarning(UserWarning):
    """The chain stopped at ``max_steps`` before the autocorrelation criterion was met."""


@dataclass(frozen=True, eq=False)
class SampleResult:
    """Posterior draws of u after burn-in and thinning (emcee ensemble: chain = walker).

    Shapes: ``chain`` (draws, walkers, dim) in the unconstrained space u;
    ``log_prob`` (draws, walkers), log posterior density of u up to a constant;
    ``acceptance_rate`` (draws, walkers), fraction of the steps in each draw's thinning
    window in which the walker moved; ``tau`` (dim) integrated autocorrelation time per
    entry of u, in steps; ``acceptance_fraction`` (walkers) over the whole run.
    """

    chain: np.ndarray
    log_prob: np.ndarray
    tau: np.ndarray
    n_steps: int  # steps per walker in the whole run (burn-in included)
    burn_in: int  # steps dropped at the start
    thin: int  # one draw kept every ``thin`` steps
    acceptance_fraction: np.ndarray
    converged: bool
    reason: str  # why not converged ("" when converged)
    names: tuple  # names of the entries of u (``problem.names(run_names)``)
    acceptance_rate: np.ndarray | None = None
    moves: str = MOVES_DESCRIPTION
    seed: int | None = None
    tau_history: tuple = field(default_factory=tuple)  # (n_steps, max τ) at every check
    stopped_early: bool = False  # ``stop_when`` ended the run (``reason`` says why)

    sampler = "emcee"  # class attribute, not a field: the sampler that made the draws

    @property
    def n_walkers(self) -> int:
        return int(self.chain.shape[1])

    @property
    def n_draws(self) -> int:
        """Kept draws per walker."""
        return int(self.chain.shape[0])

    @property
    def tau_max(self) -> float:
        return float(np.max(self.tau))

    def flat(self) -> np.ndarray:
        """All kept draws as (draws · walkers, dim)."""
        return self.chain.reshape(-1, self.chain.shape[-1])


# --- the log-density handed to emcee -----------------------------------------------------
def _log_density_one(problem, u):
    lp = problem.log_density(u)
    return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)


#: log-density of a batch of u (n, dim) → (n,); compiled once per problem shape and batch size,
#: with the MAP's XLA options (``fit._map.MAP_COMPILER_OPTIONS``): on the SYNTHETIC 10k loop of
#: benchmarks/bench_full_fit.py XLA compiled it in 0.37 s instead of 0.65 s, and a call took as
#: long (3.03 ms both, 16 walkers, 400 interleaved calls on a loaded machine) and gave the same
#: log-densities bit for bit
batch_log_density = _map_jit(eqx.filter_vmap(_log_density_one, in_axes=(None, 0)))


class _StaticParts:
    """The non-array part of a problem (with the layout of its arrays): the static argument of
    :func:`_split_batch_log_density`, hashed once. Problems that differ only in their arrays'
    values share one compiled program, as with ``eqx.filter_jit``."""

    def __init__(self, array_tree, static):
        static_leaves, static_tree = jtu.tree_flatten(static)
        self.parts = (array_tree, static_tree, tuple(static_leaves))
        self._hash = hash(self.parts)

    def __hash__(self):
        return self._hash

    def __eq__(self, other):
        return isinstance(other, _StaticParts) and self.parts == other.parts

    def problem(self, arrays):
        array_tree, static_tree, static_leaves = self.parts
        return eqx.combine(jtu.tree_unflatten(array_tree, arrays), jtu.tree_unflatten(static_tree, static_leaves))


def _split_batch_log_density(static: _StaticParts, arrays, u):
    return jax.vmap(functools.partial(_log_density_one, static.problem(arrays)))(u)


@functools.cache
def _split_program():
    return jax.jit(_split_batch_log_density, static_argnums=0, compiler_options=_map_compiler_options())


def bound_log_density(problem):
    """``chunk ↦ batch_log_density(problem, chunk)`` with the problem split into its arrays and
    its static part once, not at every call: ``eqx.filter_jit`` partitions and hashes the whole
    problem on each call, ~0.1 ms of a 1.5 ms call on the SYNTHETIC 10k loop of
    benchmarks/bench_full_fit.py, and emcee calls it twice per step. Same program, same
    log-densities bit for bit (tests/test_sample.py)."""
    arrays, static = eqx.partition(problem, eqx.is_array)
    leaves, array_tree = jtu.tree_flatten(arrays)
    key = _StaticParts(array_tree, static)
    program = _split_program()
    return lambda chunk: program(key, leaves, chunk)


def _value_and_grad_one(problem, u):
    lp, g = jax.value_and_grad(problem.log_density)(u)
    ok = jnp.isfinite(lp) & jnp.all(jnp.isfinite(g))
    return jnp.where(ok, lp, -jnp.inf), jnp.where(ok, g, 0.0)


#: log-density and gradient of a batch of u (n, dim) → ((n,), (n, dim)): −inf and a zero
#: gradient where either is not finite; compiled once per problem shape and batch size
batch_log_density_and_grad = _map_jit(eqx.filter_vmap(_value_and_grad_one, in_axes=(None, 0)))


class _LogProbGrad:
    """NumPy (n, dim) → (log density (n,), gradient (n, dim)) in chunks of ``batch`` rows (one
    compiled shape; the last chunk padded): −inf and a zero gradient off the support, never NaN
    (tempered SMC's HMC moves)."""

    def __init__(self, problem, batch: int = 64):
        self.problem, self.batch = problem, int(batch)

    def __call__(self, coords):
        coords = np.atleast_2d(np.asarray(coords, dtype=float))
        ok = np.all(np.isfinite(coords), axis=1)
        safe = np.where(ok[:, None], coords, 0.0) if not ok.all() else coords
        lp, g = map_chunks(lambda c: batch_log_density_and_grad(self.problem, c), safe, self.batch)
        lp, g = np.array(lp, dtype=float), np.array(g, dtype=float)
        bad = ~ok | ~np.isfinite(lp)
        lp[bad], g[bad] = -np.inf, 0.0
        return lp, g


class _LogProb:
    """NumPy wrapper for emcee (``vectorize=True``): (n, dim) → (n,), never NaN.

    Every call is evaluated in chunks of ``batch`` rows (the last one padded), so the JAX
    function compiles for one batch shape only: emcee asks for the whole ensemble once and
    for half of it at every step. ``evaluate`` (chunk → log-densities) replaces the default
    ``batch_log_density(problem, chunk)``: ``torsionfit.batch`` evaluates the chunks of many
    units' samplers in one call."""

    def __init__(self, problem, batch: int | None = None, evaluate=None):
        self.problem = problem
        self.batch = batch
        # the NumPy chunk goes to the compiled function as it is: jit's own transfer was
        # ~0.4 ms per call faster than a jnp.asarray first (16 walkers, 10 001 samples)
        self.evaluate = evaluate or bound_log_density(problem)

    def __call__(self, coords) -> np.ndarray:
        coords = np.atleast_2d(np.asarray(coords, dtype=float))
        ok = np.all(np.isfinite(coords), axis=1)
        # non-finite rows are replaced by a finite one (then rejected) so that no inf or
        # NaN ever enters the JAX function
        safe = np.where(ok[:, None], coords, 0.0) if not ok.all() else coords
        if len(safe) == self.batch:  # emcee's every step: one chunk, no padding to do
            lp = np.array(self.evaluate(safe), dtype=float)
        else:
            lp = np.array(map_chunks(self.evaluate, safe, self.batch or len(safe)), dtype=float)
        lp[~ok | ~np.isfinite(lp)] = -np.inf
        return lp


# --- HDF5 backend ----------------------------------------------------------------------------
class BufferedHDFBackend(emcee.backends.HDFBackend):
    """emcee's HDF5 backend, writing steps in blocks of ``flush_every``.

    emcee's own ``HDFBackend`` opens the file four times per step (≈ 18 ms per step measured
    here, three times the cost of the log-density of a small campaign). This one keeps the
    steps in memory and writes them in one go — every ``flush_every`` steps, before any
    read, and when ``flush()`` is called (``run_sampler`` does after every block, also on an
    interruption). The file layout is emcee's: ``emcee.backends.HDFBackend(path)`` reads it
    and resumes from it. Blobs are not supported (``run_sampler`` uses none).
    """

    def __init__(self, filename, name: str = "mcmc", flush_every: int = 100, **kwargs):
        super().__init__(filename, name=name, **kwargs)
        self.flush_every = int(flush_every)
        self._buffer: list = []
        self._shape = None
        #: () → dict of int attributes stored with every step (a move's counters), or None
        self.step_attrs = None

    def reset(self, nwalkers, ndim):
        self._buffer = []
        super().reset(nwalkers, ndim)
        self._shape = (int(nwalkers), int(ndim))

    def flush(self) -> None:
        """Write the buffered steps (chain, log_prob, accepted counts, last random state)."""
        if not self._buffer:
            return
        buf, self._buffer = self._buffer, []
        with self.open("a") as f:
            g = f[self.name]
            it = int(g.attrs["iteration"])
            n = len(buf)
            for key in ("chain", "log_prob"):
                if g[key].shape[0] < it + n:
                    g[key].resize(it + n, axis=0)
            g["chain"][it:it + n] = np.stack([b[0] for b in buf])
            g["log_prob"][it:it + n] = np.stack([b[1] for b in buf])
            g["accepted"][:] += np.sum([b[2] for b in buf], axis=0)
            for i, v in enumerate(buf[-1][3]):
                g.attrs[f"random_state_{i}"] = v
            for k, v in buf[-1][4].items():  # as they were after the last stored step
                g.attrs[k] = v
            g.attrs["iteration"] = it + n

    def save_step(self, state, accepted):
        if state.blobs is not None:
            raise ValueError("BufferedHDFBackend does not store blobs")
        if self._shape is None:
            self._shape = tuple(int(x) for x in super().shape)
        if np.shape(state.coords) != self._shape or np.shape(accepted) != self._shape[:1]:
            raise ValueError(f"invalid step shape; expected {self._shape} walkers × dim")
        self._buffer.append((np.array(state.coords, dtype=float), np.array(state.log_prob, dtype=float),
                             np.asarray(accepted, dtype=float), state.random_state,
                             self.step_attrs() if self.step_attrs else {}))
        if len(self._buffer) >= self.flush_every:
            self.flush()

    # every read sees the buffered steps: write them first
    def grow(self, ngrow, blobs):
        self.flush()
        super().grow(ngrow, blobs)

    def get_value(self, name, flat=False, thin=1, discard=0):
        self.flush()
        return super().get_value(name, flat=flat, thin=thin, discard=discard)

    @property
    def iteration(self):
        self.flush()
        return super().iteration

    @property
    def accepted(self):
        self.flush()
        return super().accepted

    @property
    def random_state(self):
        self.flush()
        return super().random_state


# --- set-up ------------------------------------------------------------------------------
def moves(u_map, cov) -> list:
    """The move mixture (see the module docstring): Laplace independence 0.5, DE 0.4, stretch 0.1."""
    return [(LaplaceMove(u_map, _regularised_cov(cov)), 0.5), (emcee.moves.DEMove(), 0.4),
            (emcee.moves.StretchMove(), 0.1)]


def default_n_walkers(dim: int) -> int:
    """``max(32, 2·dim + 2)`` rounded up to an even number."""
    n = max(32, 2 * int(dim) + 2)
    return n + (n % 2)


def _regularised_cov(cov: np.ndarray, fallback_sd: float = 1e-3, min_eig: float = 1e-6) -> np.ndarray:
    """A positive-definite version of a Laplace covariance: zero / non-finite variances get
    ``fallback_sd``² (units of u), the correlation matrix's eigenvalues are floored at
    ``min_eig`` (keeps the starting ensemble linearly independent, which emcee checks)."""
    cov = np.array(cov, dtype=float)
    cov = 0.5 * (cov + cov.T)
    cov[~np.isfinite(cov)] = 0.0
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    bad = ~(sd > 0)
    sd[bad] = fallback_sd
    corr = cov / np.outer(sd, sd)
    corr[bad, :] = 0.0
    corr[:, bad] = 0.0
    np.fill_diagonal(corr, 1.0)
    w, v = np.linalg.eigh(corr)
    corr = (v * np.maximum(w, min_eig)) @ v.T
    d = np.sqrt(np.diag(corr))
    corr = corr / np.outer(d, d)
    return corr * np.outer(sd, sd)


def initial_walkers(problem, u_map, cov, n_walkers: int, rng: np.random.Generator,
                    max_rounds: int = 100, evaluate=None) -> np.ndarray:
    """(n_walkers, dim) draws from N(u_map, cov) (cov regularised), each re-drawn until its
    log-density is finite. RuntimeError when some walker never gets a finite value.
    ``evaluate``: as for :class:`_LogProb`."""
    u_map = np.asarray(u_map, dtype=float)
    chol = np.linalg.cholesky(_regularised_cov(cov))
    logp = _LogProb(problem, batch=max(n_walkers // 2, 1), evaluate=evaluate)  # the sampler's batch shape
    walkers = np.empty((n_walkers, u_map.size))
    todo = np.ones(n_walkers, dtype=bool)
    for _ in range(max_rounds):
        walkers[todo] = u_map + rng.standard_normal((int(todo.sum()), u_map.size)) @ chol.T
        todo = ~np.isfinite(logp(walkers))
        if not todo.any():
            return walkers
    raise RuntimeError(
        f"{int(todo.sum())} of {n_walkers} walkers had a non-finite log-density in {max_rounds} draws "
        "from the Laplace approximation; check the MAP fit"
    )


# --- convergence bookkeeping --------------------------------------------------------------
def _tau(sampler) -> np.ndarray:
    """τ per parameter (steps); NaN (a parameter that never moved) becomes +inf."""
    tau = np.asarray(sampler.get_autocorr_time(tol=0), dtype=float)
    return np.where(np.isfinite(tau), tau, np.inf)


def _check(tau, tau_prev, n_steps, tau_factor, tau_rtol, min_steps, names) -> tuple[bool, str]:
    """(converged, reason) by the emcee recipe; the reason names the shortfall."""
    i = int(np.argmax(tau))
    tau_max = float(tau[i])
    who = names[i] if names is not None and i < len(names) else f"u[{i}]"
    if not np.isfinite(tau_max):
        return False, f"the autocorrelation time of {who} is undefined (the walkers did not move)"
    if n_steps <= tau_factor * tau_max:
        return False, (f"chain of {n_steps} steps is shorter than {tau_factor:g} × τ_max = "
                       f"{tau_factor * tau_max:.0f} steps (τ_max = {tau_max:.1f} for {who})")
    if tau_prev is None:
        return False, "τ was estimated only once; its stability could not be checked"
    # stability of max τ, the value that sets the required length and the burn-in (see the
    # module docstring for why not of every τ), unless the chain is twice as long as needed
    change = abs(float(np.max(tau_prev)) - tau_max) / tau_max
    long_enough = n_steps > 2 * tau_factor * max(tau_max, float(np.max(tau_prev)))
    if not (change < tau_rtol or long_enough):
        return False, (f"τ_max still changing: {100 * change:.1f} % since the last check "
                       f"(limit {100 * tau_rtol:g} %; τ_max = {tau_max:.1f} for {who})")
    if n_steps < min_steps:
        return False, f"only {n_steps} steps, fewer than min_steps = {min_steps}"
    return True, ""


def _judge(sampler, tau, tau_prev, tau_factor, tau_rtol, min_steps, names) -> tuple[bool, str]:
    """(converged, reason): the τ rule (:func:`_check`), then the R̂ and ESS rule every sampler
    is judged by (``_convergence``) on the kept draws (after burn-in and thinning, walkers as
    chains) — a chain 50 τ long can still hold a walker that wandered apart (R̂) or too few
    independent draws of a parameter whose τ was underestimated (ESS)."""
    converged, reason = _check(tau, tau_prev, sampler.iteration, tau_factor, tau_rtol, min_steps, names)
    if not converged:
        return False, reason
    burn, thin = _burn_thin(tau, int(sampler.iteration))
    kept = np.asarray(sampler.get_chain(discard=burn, thin=thin))
    rhat, bulk, tail = chain_diagnostics(kept)
    reason = rhat_ess_shortfall(rhat, bulk, tail, kept.shape[0], names, per="kept draws per walker")
    return not reason, reason


def _burn_thin(tau: np.ndarray, n_steps: int) -> tuple[int, int]:
    """Burn-in ⌈2 max τ⌉ and thinning max(1, ⌊min τ / 2⌋), capped so that at least half of
    the chain and at least two draws per walker remain."""
    finite = tau[np.isfinite(tau)]
    tau_max = float(np.max(finite)) if finite.size else math.inf
    tau_min = float(np.min(finite)) if finite.size else 1.0
    burn = int(math.ceil(2.0 * tau_max)) if np.isfinite(tau_max) else n_steps // 2
    burn = min(burn, n_steps // 2)
    thin = max(1, int(tau_min // 2))
    thin = max(1, min(thin, (n_steps - burn) // 2))
    return burn, thin


def _acceptance_windows(full_chain: np.ndarray, burn: int, thin: int) -> np.ndarray:
    """Fraction of steps in which each walker moved, over the ``thin`` steps that end at each
    kept draw (emcee keeps steps burn + thin − 1, burn + 2·thin − 1, …). The first step of
    the run has no predecessor here and is left out of its window."""
    moved = np.zeros(full_chain.shape[:2])
    moved[1:] = np.any(full_chain[1:] != full_chain[:-1], axis=-1)
    counted = np.ones(full_chain.shape[0])
    counted[0] = 0.0
    kept = np.arange(burn + thin - 1, full_chain.shape[0], thin)
    out = np.empty((kept.size, full_chain.shape[1]))
    for k, t in enumerate(kept):
        lo = t - thin + 1
        out[k] = moved[lo:t + 1].sum(axis=0) / max(counted[lo:t + 1].sum(), 1.0)
    return out


# --- the sampler ----------------------------------------------------------------------------
@in_float64
def run_sampler(problem, map_result, *, seed: int, n_walkers: int | None = None,
                max_steps: int = 20_000, check_every: int = 500, tau_factor: float = 50.0,
                min_steps: int = 1000, tau_rtol: float = 0.01,
                backend_path: str | os.PathLike | None = None, resume: bool = False,
                progress: bool = True, evaluate=None, stop_when=None) -> SampleResult:
    """Sample the posterior of ``problem`` with emcee, started from ``map_result``'s Laplace
    approximation (``.u``, ``.cov``; ``.names`` used for messages and the result).

    ``max_steps``, ``check_every``, ``min_steps`` and the result's ``n_steps``/``burn_in``/
    ``thin``/``tau`` count ensemble steps (one step moves every walker once). With
    ``backend_path`` every step is stored in that HDF5 file; ``resume=True`` continues the
    chain stored there (its walker count is used; ``max_steps`` counts the stored steps too),
    and starts afresh when the file holds no chain. Without ``resume`` an existing chain in
    the file is overwritten. A chain that reaches ``max_steps`` unconverged is returned with
    ``converged=False`` and a :class:`ConvergenceWarning`. ``evaluate`` maps a
    (n_walkers/2, dim) chunk of u to its log-densities (default: ``batch_log_density`` of
    ``problem``; ``torsionfit.batch`` passes one shared by many units' samplers).
    ``stop_when(n_steps, tau)``, called at every check of an unconverged chain, may return a
    reason to give up: the run ends there with ``converged=False``, ``stopped_early=True``
    and that reason, without a warning (``--sampler auto`` hands the posterior to NUTS).
    """
    dim = int(problem.dim)
    if check_every < 1 or max_steps < 1:
        raise ValueError("check_every and max_steps must be positive")
    names = tuple(getattr(map_result, "names", None) or (f"u[{i}]" for i in range(dim)))
    asked_walkers = n_walkers
    n_walkers = default_n_walkers(dim) if n_walkers is None else int(n_walkers)
    if n_walkers < 2 * dim or n_walkers % 2:
        raise ValueError(f"n_walkers must be even and at least 2·dim = {2 * dim}, got {n_walkers}")

    backend, start = None, None
    if backend_path is not None:
        backend = BufferedHDFBackend(os.fspath(backend_path))
        if resume and backend.initialized and backend.iteration > 0:
            stored_walkers, stored_dim = (int(x) for x in backend.shape)
            if stored_dim != dim:
                raise ValueError(f"{backend_path}: the stored chain has dimension {stored_dim}, "
                                 f"the problem {dim}; it is not this problem's chain")
            if asked_walkers is not None and int(asked_walkers) != stored_walkers:
                raise ValueError(f"{backend_path}: the stored chain has {stored_walkers} walkers, "
                                 f"n_walkers = {asked_walkers} was asked for")
            n_walkers = stored_walkers  # continue with the stored ensemble
        else:
            backend.reset(n_walkers, dim)
    resumed = backend is not None and backend.iteration > 0

    mixture = moves(map_result.u, map_result.cov)
    laplace = mixture[0][0]
    sampler = emcee.EnsembleSampler(
        n_walkers, dim, _LogProb(problem, batch=n_walkers // 2, evaluate=evaluate), vectorize=True, backend=backend,
        moves=mixture,
    )
    # emcee wraps the log-density in a function that prints every walker's position on any
    # exception, Ctrl-C included (hundreds of lines); ours takes no extra arguments to carry
    sampler.log_prob_fn = sampler.log_prob_fn.f
    if backend is not None:
        backend.step_attrs = laplace.counters
    tau_prev = None
    if resumed:
        # the backend's last state, random state and the Laplace move's counters carry on
        # where the run stopped
        with backend.open() as f:
            laplace.restore(f[backend.name].attrs)
        _retire_if_rejected(laplace, sampler.iteration, check_every)
        tau_prev = _tau(sampler) if sampler.iteration > 1 else None
    else:
        rng = np.random.default_rng(seed)
        start = initial_walkers(problem, map_result.u, map_result.cov, n_walkers, rng, evaluate=evaluate)
        sampler.random_state = np.random.RandomState(seed).get_state()

    converged, reason, history, stopped = False, "", [], False
    tau = tau_prev
    while sampler.iteration < max_steps:
        # blocks end on multiples of check_every, so a resumed run checks (and retires the
        # Laplace move) at the same steps as an uninterrupted one
        n = min(check_every - sampler.iteration % check_every, max_steps - sampler.iteration)
        done = sampler.iteration
        try:
            sampler.run_mcmc(start, n, progress=progress,
                             progress_kwargs={"desc": f"emcee {done + n}/{max_steps}", "leave": False})
        finally:  # an interrupted block keeps its completed steps on disk
            if backend is not None:
                backend.flush()
        start = None  # later blocks continue from the sampler's last state
        _retire_if_rejected(laplace, sampler.iteration, check_every)
        tau = _tau(sampler)
        history.append((int(sampler.iteration), float(np.max(tau))))
        converged, reason = _judge(sampler, tau, tau_prev, tau_factor, tau_rtol, min_steps, names)
        if converged:
            break
        log.info("emcee: %s", steps_left(int(sampler.iteration), float(np.max(tau)), tau_factor, min_steps, max_steps))
        if stop_when is not None:
            why = stop_when(int(sampler.iteration), tau)
            if why:
                reason, stopped = why, True
                break
        tau_prev = tau
    if not history:  # resumed a chain that already had max_steps steps: judge it as it is
        tau = _tau(sampler)
        converged, reason = _judge(sampler, tau, None, tau_factor, tau_rtol, min_steps, names)
    n_steps = int(sampler.iteration)
    if not converged and not stopped:
        reason = f"not converged after {n_steps} steps (max_steps = {max_steps}): {reason}"
        warnings.warn(f"emcee: {reason}", ConvergenceWarning, stacklevel=3)  # 3: past the float64 wrapper

    burn, thin = _burn_thin(tau, n_steps)
    full = sampler.get_chain()
    return SampleResult(
        chain=np.asarray(sampler.get_chain(discard=burn, thin=thin)),
        log_prob=np.asarray(sampler.get_log_prob(discard=burn, thin=thin)),
        tau=np.asarray(tau, dtype=float),
        n_steps=n_steps,
        burn_in=burn,
        thin=thin,
        acceptance_fraction=np.asarray(sampler.acceptance_fraction, dtype=float),
        converged=bool(converged),
        reason=reason,
        names=names,
        acceptance_rate=_acceptance_windows(np.asarray(full), burn, thin),
        seed=seed,
        tau_history=tuple(history),
        stopped_early=stopped,
        moves=MOVES_DESCRIPTION + (f"; LaplaceMove retired at step {check_every} (acceptance "
                                   f"{laplace.acceptance:.3f} < {RETIRE_BELOW}), its share to DEMove"
                                   if laplace.retired else ""),
    )


def steps_left(n_steps: int, tau_max: float, tau_factor: float, min_steps: int, max_steps: int) -> str:
    """Progress text: steps done and an estimate of those left — to ``tau_factor`` · τ_max (τ
    from the chain so far, an estimate that grows with the chain) and ``min_steps``, at most
    ``max_steps``."""
    need = max(tau_factor * tau_max, min_steps) if np.isfinite(tau_max) else math.inf
    left = min(need, max_steps) - n_steps
    if not np.isfinite(need):
        return f"{n_steps} steps of at most {max_steps}; the walkers have not moved enough to estimate τ yet"
    return (f"{n_steps} steps of at most {max_steps}; τ_max ≈ {tau_max:.1f} → about {max(left, 0):.0f} more "
            f"(needs {tau_factor:g} τ_max ≈ {need:.0f}" + (", beyond the cap" if need > max_steps else "") + ")")


def _retire_if_rejected(laplace, iteration: int, check_every: int) -> None:
    """At the first check (step ``check_every``), retire the Laplace move when its proposals
    were accepted less often than :data:`RETIRE_BELOW` (once, at a fixed step: see
    ``_laplace_move.py``)."""
    if iteration == check_every and not laplace.retired and laplace.acceptance < RETIRE_BELOW:
        laplace.retire()
