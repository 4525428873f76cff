"""Tempered sequential Monte Carlo from an approximation q to the posterior p.

Where the split normal along the Laplace axes does not stand for the posterior (Pareto k of p/q
at its draws above 0.7) no weighting of its draws recovers the posterior, and on measured loops
emcee's walkers and NUTS's trajectories cross it too slowly. Tempering bridges the two: particles
drawn from q are carried through the densities

    π_β(u) ∝ q(u)^(1 − β) · p(u)^β,   β = 0 → 1,

each step's β chosen so that the incremental weights (p/q)^Δβ keep an effective sample size of
``target_ess`` of the particles; the particles are then resampled (systematic) and moved by
Markov steps that leave π_β invariant. Given the posterior's gradient (``log_p_and_grad``) each
move is a Hamiltonian Monte Carlo trajectory, the mass matrix the inverse of the particles'
covariance (so a step crosses the particles' spread along every axis alike), the step size h
tuned towards an acceptance of 0.65 (Beskos et al. 2013) and the trajectory's length fixed in
those whitened units: ⌈T/h⌉ leapfrog steps for T = :data:`HMC_TRAJECTORY_LENGTH` (a quarter
period of a Gaussian of the particles' covariance: one move draws a new position of it), at most
:data:`HMC_MAX_LEAPFROG_STEPS`; each move's step is h divided by a log-uniform factor up to
:data:`HMC_STEP_SPREAD`. Where the posterior narrows somewhere (a funnel: one coordinate setting
another's spread) the step tuned over the population is too long for the particles there, and
with one step they stayed put while the rest mixed. Without it
(a posterior given as values alone) random-walk Metropolis steps with the particles' covariance
scaled by a factor tuned towards an acceptance of 0.234, every other move an independence
proposal from the particles' Gaussian (inflated by ``INDEPENDENT_INFLATION``): on measured loops
these did not forget their start within 100 moves near β = 1 (largest correlation 0.28–0.59).
The moves go on until every coordinate's
correlation with the particles' positions at the start of the stage has fallen to
``decorrelation`` — the particles have forgotten where resampling put them — or
``max_moves`` is reached (``final_max_moves`` at β = 1), which counts as not converged. Where the moved particles sit in
modes separated by many of their widths (:mod:`._modes`), the correlation is measured
within them: the moves do not cross between such modes, and the particles' shares in them come
from the tempering's weights, not from the moves. At β = 1 the particles are equally
weighted draws of p (Del Moral, Doucet & Jasra 2006; Chopin & Papaspiliopoulos 2020, ch. 17).

The sampler calls the posterior (and its gradient) in batches (one compiled program for all
particles). BlackJAX's tempered SMC would need q's log density and the whole loop inside one
jitted JAX program; here q is the split normal of :mod:`._split_normal` (NumPy) and the
posterior is a batched program.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from scipy.linalg import solve_triangular
from scipy.stats import norm

from . import _smc_checkpoint as ckpt
from ._emcee import SampleResult
from ._modes import correlations_with_start
from ._pareto import importance_pareto_k

#: the acceptance the random walk's scale is tuned towards (Roberts, Gelman & Gilks 1997)
TARGET_ACCEPTANCE = 0.234

#: the independence proposal's covariance is the particles' times this squared (heavier reach)
INDEPENDENT_INFLATION = 1.3

#: the acceptance HMC's step size is tuned towards (Beskos et al. 2013: 0.651 optimal as dim → ∞)
HMC_TARGET_ACCEPTANCE = 0.65
#: each HMC move's step size is the tuned one divided by a log-uniform factor between 1 and this:
#: the particles where the posterior is narrower than the population's tuned step allows move on
#: the short draws (and no one trajectory length resonates with a period of the posterior)
HMC_STEP_SPREAD = 30.0
#: the HMC trajectory's length in units of the particles' spread (whitened by their covariance):
#: π/2, a quarter period of a Gaussian of that covariance
HMC_TRAJECTORY_LENGTH = 0.5 * np.pi
#: the most leapfrog steps (gradient evaluations) one HMC move takes
HMC_MAX_LEAPFROG_STEPS = 64

__all__ = ["SMCResult", "tempered_smc"]


def _gauss_log(x: np.ndarray, mean: np.ndarray, chol: np.ndarray) -> np.ndarray:
    """log N(x; mean, chol·cholᵀ) up to the constant (the same for every x)."""
    z = np.linalg.solve(chol, (x - mean).T)
    return -0.5 * np.sum(z**2, axis=0)


#: the per-stage lists of a run, kept in its checkpoint by these names
_TRACE = ("betas", "moves", "accept", "corr", "slowest", "steps", "modes", "trajectory", "budgets")


@dataclasses.dataclass(frozen=True, eq=False)
class SMCResult(SampleResult):
    """Equally weighted particles of the posterior as one chain: ``chain`` (particles, 1, dim),
    ``log_prob`` (particles, 1). ``betas``: the tempering schedule (last 1.0 when it reached the
    posterior); per stage ``moves`` (random-walk steps), ``stage_acceptance`` and
    ``stage_correlation`` (the largest |correlation| of a coordinate with its value at the start
    of the stage, after the moves, within the stage's separated modes: ``stage_modes``);
    ``approximation_pareto_k``: the Pareto k of p/q at q's draws
    (how far the approximation was from the posterior); ``stage_step_size``: HMC's step size
    per stage (empty for random-walk moves)."""

    betas: tuple = ()
    stage_moves: tuple = ()
    stage_acceptance: tuple = ()
    stage_correlation: tuple = ()
    approximation_pareto_k: float = float("nan")
    #: HMC moves: each stage's step size (in the particles' scale); empty for random-walk moves
    stage_step_size: tuple = ()
    #: HMC moves: each stage's mean leapfrog steps per move (gradient evaluations per particle)
    stage_leapfrog_steps: tuple = ()
    #: per stage the separated modes among the particles after its moves (:mod:`._modes`): the
    #: moves do not cross between them, and ``stage_correlation`` is measured within them
    stage_modes: tuple = ()
    #: the share of the particles in each mode after the last stage's moves (one entry: one mode)
    mode_shares: tuple = ()
    #: the largest |correlation| with the start that particles which forgot it show at one check
    #: in two (:func:`correlation_floor`): where it exceeds the decorrelation asked, the particles
    #: are too few for the check to resolve it
    correlation_floor: float = float("nan")
    #: per stage the moves it was allowed (``max_moves``; ``final_max_moves`` at β = 1)
    stage_max_moves: tuple = ()

    sampler = "smc"


def correlation_floor(n_particles: int, dim: int, probability: float = 0.5) -> float:
    """The largest |correlation| over ``dim`` coordinates between the positions of
    ``n_particles`` particles and positions independent of them that is not exceeded with
    ``probability``: each correlation ≈ N(0, 1/(n − 1)), so the largest is below t with
    probability P(|Z| ≤ t·√(n − 1))^dim. The noise of the decorrelation check: with 500
    particles and 31 coordinates 0.10 at one check in two — a population that forgot its start
    passes a 0.1 rule at about half the checks, and with 200 particles at almost none."""
    if n_particles < 3 or dim < 1:
        return float("nan")
    return _largest_z(dim, probability) / float(np.sqrt(n_particles - 1))


def _largest_z(dim: int, probability: float) -> float:
    """The |Z| the largest of ``dim`` independent standard normals stays within with ``probability``."""
    return float(norm.ppf(0.5 + 0.5 * probability ** (1.0 / dim)))


def particles_resolving(decorrelation: float, dim: int, probability: float = 0.9) -> int:
    """The fewest particles for which independent positions stay within ``decorrelation`` over
    ``dim`` coordinates with ``probability`` (the inverse of :func:`correlation_floor`)."""
    return int(np.ceil((_largest_z(dim, probability) / decorrelation) ** 2 + 1))


def _incremental_weights(log_ratio: np.ndarray, delta: float) -> np.ndarray:
    """(p/q)^Δβ per particle, scaled to a largest of 1 (``log_ratio`` −inf: weight 0; Δβ > 0)."""
    w = delta * log_ratio
    return np.exp(w - np.max(w))


def _next_beta(log_ratio: np.ndarray, beta: float, target_ess: float) -> float:
    """The largest β' ≤ 1 whose incremental weights (p/q)^(β'−β) keep an ESS of ``target_ess``
    of the particles (bisection; the ESS falls as β' grows)."""

    def ess(delta: float) -> float:
        w = _incremental_weights(log_ratio, delta)
        return float(w.sum() ** 2 / (w**2).sum() / w.size)

    if ess(1.0 - beta) >= target_ess:
        return 1.0
    lo, hi = 0.0, 1.0 - beta
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ess(mid) >= target_ess else (lo, mid)
    return beta + max(lo, 1e-12)


def _systematic(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    n = weights.size
    idx = np.searchsorted(np.cumsum(weights), (rng.random() + np.arange(n)) / n)
    return np.minimum(idx, n - 1)


def _particle_covariance(x: np.ndarray) -> np.ndarray:
    """The particles' covariance with a tiny ridge (a positive definite one for Cholesky)."""
    dim = x.shape[1]
    cov = np.cov(x, rowvar=False).reshape(dim, dim)
    return cov + 1e-12 * (np.trace(cov) / dim + 1e-300) * np.eye(dim)


def _tempered(beta: float, lp: np.ndarray, lq: np.ndarray) -> np.ndarray:
    """log π_β = β log p + (1 − β) log q, −inf where p is zero (β > 0)."""
    return np.where(np.isfinite(lp), beta * lp + (1.0 - beta) * lq, -np.inf)


class _RandomWalk:
    """Random-walk Metropolis with the particles' covariance (its scale tuned towards
    :data:`TARGET_ACCEPTANCE`), alternating with independence proposals from their Gaussian."""

    def __init__(self, log_p, approximation, dim: int):
        self.log_p, self.approximation = log_p, approximation
        self.scale = 2.38 / np.sqrt(dim)

    def tuned(self) -> dict:
        """What the kernel has tuned so far (a checkpoint's part)."""
        return {"scale": float(self.scale)}

    def restore(self, tuned: dict) -> None:
        self.scale = float(tuned["scale"])

    def start_stage(self, x, beta):
        self.beta = beta
        self.chol = np.linalg.cholesky(_particle_covariance(x))
        self.mean = x.mean(axis=0)
        self.ind_chol = INDEPENDENT_INFLATION * self.chol

    def move(self, m: int, state, rng) -> float | None:
        """One move of every particle (``state``: x, lp, lq, updated in place); the random
        walk's acceptance, None for an independence move."""
        x, lp, lq = state
        n, dim = x.shape
        # every other move proposes afresh from the particles' Gaussian (inflated): where π_β is
        # near it one accepted move forgets the start; the random walk handles the rest
        independent = m % 2 == 0
        if independent:
            prop = self.mean + rng.standard_normal((n, dim)) @ self.ind_chol.T
        else:
            prop = x + self.scale * rng.standard_normal((n, dim)) @ self.chol.T
        lp_new = np.asarray(self.log_p(prop), float)
        lq_new = np.asarray(self.approximation.log_density(prop), float)
        log_a = _tempered(self.beta, lp_new, lq_new) - _tempered(self.beta, lp, lq)
        if independent:
            log_a = log_a - _gauss_log(prop, self.mean, self.ind_chol) + _gauss_log(x, self.mean, self.ind_chol)
        ok = np.log(rng.random(n)) < np.where(np.isfinite(log_a), log_a, -np.inf)
        x[ok], lp[ok], lq[ok] = prop[ok], lp_new[ok], lq_new[ok]
        if independent:
            return None
        self.scale *= float(np.exp(ok.mean() - TARGET_ACCEPTANCE))  # the population's rate, not a particle's
        return float(ok.mean())


class _Hamiltonian:
    """HMC, mass matrix the inverse of the particles' covariance C (momentum ~ N(0, C⁻¹),
    velocity C·p), the step size h tuned towards :data:`HMC_TARGET_ACCEPTANCE` over the
    population; ``leapfrog_steps`` per move, or (None) ⌈T/h⌉ for T = :data:`HMC_TRAJECTORY_LENGTH`,
    at most :data:`HMC_MAX_LEAPFROG_STEPS`. ``log_p_and_grad``: (n, dim) → ((n,),
    (n, dim)), −inf and a zero gradient where p is zero; the approximation's gradient is
    ``approximation.grad_log_density``."""

    def __init__(self, log_p_and_grad, approximation, dim: int, leapfrog_steps: int | None):
        self.log_p_and_grad, self.approximation = log_p_and_grad, approximation
        self.leapfrog_steps = None if leapfrog_steps is None else int(leapfrog_steps)
        self.step = 1.0 / dim ** 0.25
        self.steps_taken = []  # leapfrog steps of each move (gradient evaluations per particle)

    def tuned(self) -> dict:
        """What the kernel has tuned so far, and the trajectories' lengths (a checkpoint's part)."""
        return {"step": float(self.step), "steps_taken": [int(k) for k in self.steps_taken]}

    def restore(self, tuned: dict) -> None:
        self.step, self.steps_taken = float(tuned["step"]), [int(k) for k in tuned["steps_taken"]]

    def start_stage(self, x, beta):
        self.beta = beta
        self.cov = _particle_covariance(x)
        self.chol = np.linalg.cholesky(self.cov)

    def _grad(self, g_p, x):
        return self.beta * g_p + (1.0 - self.beta) * self.approximation.grad_log_density(x)

    def move(self, m: int, state, rng) -> float:
        # a trajectory that diverges (a step too long for its particle) overflows on its way out: it
        # ends with a non-finite energy and is rejected
        with np.errstate(over="ignore", invalid="ignore"):
            return self._move(state, rng)

    def _move(self, state, rng) -> float:
        x, lp, lq, gp = state
        n, dim = x.shape
        # momentum ~ N(0, C⁻¹): L⁻ᵀ ξ with C = L Lᵀ
        p0 = solve_triangular(self.chol, rng.standard_normal((dim, n)), lower=True, trans="T").T
        # the move's step: the tuned one divided by a log-uniform factor up to HMC_STEP_SPREAD. Where
        # the posterior narrows (a funnel's neck, a ridge's curved ends) the tuned step, set by the
        # population's acceptance, is too long for the particles there: the shorter draws move them
        h = self.step * HMC_STEP_SPREAD ** -rng.uniform(0.0, 1.0)
        steps = self.leapfrog_steps or int(np.clip(np.ceil(HMC_TRAJECTORY_LENGTH / h), 1, HMC_MAX_LEAPFROG_STEPS))
        self.steps_taken.append(steps)
        xn, pn = x.copy(), p0 + 0.5 * h * self._grad(gp, x)
        off = np.zeros(n, bool)  # trajectories that left the support: stopped there, then rejected
        for j in range(steps):
            xn = xn + h * pn @ self.cov
            lpn, gpn = self.log_p_and_grad(xn)
            lpn, gpn = np.asarray(lpn, float), np.asarray(gpn, float)
            off |= ~np.isfinite(lpn)
            pn = pn + (h if j < steps - 1 else 0.5 * h) * self._grad(gpn, xn)
            pn[off] = 0.0
        lqn = np.asarray(self.approximation.log_density(xn), float)
        h0 = _tempered(self.beta, lp, lq) - 0.5 * np.sum((p0 @ self.cov) * p0, axis=1)
        h1 = _tempered(self.beta, lpn, lqn) - 0.5 * np.sum((pn @ self.cov) * pn, axis=1)
        log_a = np.where(np.isfinite(h1) & np.isfinite(h0), h1 - h0, -np.inf)
        ok = np.log(rng.random(n)) < log_a
        x[ok], lp[ok], lq[ok], gp[ok] = xn[ok], lpn[ok], lqn[ok], gpn[ok]
        self.step *= float(np.exp(ok.mean() - HMC_TARGET_ACCEPTANCE))
        return float(ok.mean())


def tempered_smc(log_p, approximation, rng: np.random.Generator, n_particles: int = 1000, *,
                 log_p_and_grad=None, leapfrog_steps: int | None = None,
                 target_ess: float = 0.5, min_moves: int = 5, max_moves: int = 100,
                 final_max_moves: int | None = None,
                 decorrelation: float = 0.1, max_stages: int = 200, names=(), seed: int | None = None,
                 progress=None, checkpoint=None, resume: bool = False) -> SMCResult:
    """Draws of the posterior ``log_p`` (a function of (n, dim) u → (n,) log density, −inf where
    zero) by tempering from ``approximation`` (``draw(rng, n)``, ``log_density(x)``, and
    ``grad_log_density(x)`` for HMC moves); see the module docstring. ``log_p_and_grad``: the
    posterior's log density and gradient ((n, dim) → ((n,), (n, dim)), −inf and a zero gradient
    where it is zero): the moves are then HMC (``leapfrog_steps`` per move, None: a trajectory
    of fixed length in the particles' spread, see the module docstring), else random-walk
    Metropolis. ``final_max_moves``: the moves allowed at the last stage (β = 1; None: ``max_moves``)
    — there they are the posterior's own Markov chains, so more of them only sample it longer,
    and the particles take longest to forget their start there (the narrowest target, the
    shortest step). ``progress``: called with one line per stage. ``checkpoint``: a ``.npz`` file the state
    is written to after every stage; with ``resume`` the run goes on from it where it exists
    (and ends as the run without the stop would have: the generator's state is in it), and a
    checkpoint of other settings or of another posterior stops with one line
    (:mod:`._smc_checkpoint`)."""
    names = tuple(names)
    final_max_moves = max_moves if final_max_moves is None else int(final_max_moves)
    if final_max_moves < max_moves:
        raise ValueError(f"tempered_smc: final_max_moves must be at least max_moves ({max_moves}), got {final_max_moves}")
    min_moves = max(1, min(min_moves, max_moves))
    settings = {"particles": int(n_particles), "kernel": "random walk" if log_p_and_grad is None else "hmc",
                "leapfrog_steps": leapfrog_steps, "target_ess": float(target_ess), "min_moves": int(min_moves),
                "max_moves": int(max_moves), "final_max_moves": int(final_max_moves),
                "decorrelation": float(decorrelation), "names": list(names)}
    resumed = checkpoint is not None and resume and Path(checkpoint).is_file()
    if resumed:
        saved, record = ckpt.load_checkpoint(checkpoint)
        ckpt.check_settings(checkpoint, record["settings"], settings)
        x = np.array(saved["x"], float)
    else:
        x = np.asarray(approximation.draw(rng, n_particles), float)
    n, dim = x.shape
    lq = np.asarray(approximation.log_density(x), float)
    if log_p_and_grad is None:
        kernel = _RandomWalk(log_p, approximation, dim)
        lp = np.asarray(log_p(x), float)
        state = [x, lp, lq]
    else:
        kernel = _Hamiltonian(log_p_and_grad, approximation, dim, leapfrog_steps)
        lp, gp = (np.asarray(a, float) for a in log_p_and_grad(x))
        state = [x, lp, lq, gp]
    beta, trace = 0.0, {k: [] for k in _TRACE}
    labels = np.zeros(n, int)
    if resumed:
        # the same program at the same particles gives the same densities: anything else is another
        # problem. The run goes on with the saved values (a batch of other particles may round a
        # row's last digit differently), so it ends where the run without the stop ends
        ckpt.check_densities(checkpoint, "approximation's log density", saved["lq"], lq)
        ckpt.check_densities(checkpoint, "posterior's log density", saved["lp"], lp)
        state = [x, np.array(saved["lp"], float), np.array(saved["lq"], float)] + (
            [np.array(saved["gp"], float)] if log_p_and_grad is not None else [])
        trace = {k: list(record["trace"][k]) for k in _TRACE}
        beta, k_q, labels = float(record["beta"]), float(record["approximation_pareto_k"]), np.array(saved["labels"], int)
        kernel.restore(record["kernel"])
        rng.bit_generator.state = record["rng"]
        if progress is not None:
            progress(f"[smc] resumed from {checkpoint} after stage {len(trace['betas'])} (β = {beta:.4f})")
    else:
        k_q = importance_pareto_k(lp, lq)
    # the per-stage lists, by name in the checkpoint
    betas, moves, accept, corr, slowest, steps, modes, trajectory, budgets = (trace[k] for k in _TRACE)
    floor, floor_90 = correlation_floor(n, dim), correlation_floor(n, dim, 0.9)
    if progress is not None and floor > decorrelation and not resumed:
        progress(f"[smc] {n} particles in {dim} coordinates cannot resolve a correlation of {decorrelation} with the "
                 f"start (particles that forgot it show {floor:.2f} at one check in two; "
                 f"about {particles_resolving(decorrelation, dim)} resolve it)")
    reason = ""
    while beta < 1.0:
        if len(betas) >= max_stages:
            reason = f"the tempering took more than {max_stages} stages (β = {beta:.3g})"
            break
        lp, lq = state[1], state[2]
        log_ratio = np.where(np.isfinite(lp), lp - lq, -np.inf)
        if not np.any(np.isfinite(log_ratio)):
            reason = "no particle has a finite posterior density"
            break
        new_beta = _next_beta(log_ratio, beta, target_ess)
        w = _incremental_weights(log_ratio, new_beta - beta)
        idx = _systematic(w / w.sum(), rng)
        state = [a[idx] for a in state]
        beta = new_beta
        betas.append(beta)
        kernel.start_stage(state[0], beta)
        taken = len(getattr(kernel, "steps_taken", ()))
        start = state[0].copy()
        rates = []
        budget = final_max_moves if beta >= 1.0 else max_moves
        budgets.append(budget)
        for m in range(1, budget + 1):
            rate = kernel.move(m, state, rng)
            if rate is not None:
                rates.append(rate)
            if m < min_moves:
                continue
            # modes the moves cannot cross keep their particles: the decorrelation is asked
            # within the modes they sit in now, whose shares the tempering's weights set
            by_coordinate, labels = correlations_with_start(start, state[0], decorrelation)
            if np.max(by_coordinate) <= decorrelation:
                break
        modes.append(int(labels.max()) + 1)
        moves.append(m)
        accept.append(float(np.mean(rates)))
        corr.append(float(np.max(by_coordinate)))
        slowest.append(int(np.argmax(by_coordinate)))
        if isinstance(kernel, _Hamiltonian):
            steps.append(float(kernel.step))
            trajectory.append(float(np.mean(kernel.steps_taken[taken:])))
        if checkpoint is not None:
            ckpt.save_checkpoint(checkpoint, {"x": state[0], "lp": state[1], "lq": state[2], "labels": labels,
                                              **({"gp": state[3]} if len(state) > 3 else {})}, {
                "settings": settings, "beta": beta, "approximation_pareto_k": float(k_q),
                "kernel": kernel.tuned(), "rng": rng.bit_generator.state,
                "trace": trace})
        if progress is not None:
            progress(f"[smc] stage {len(betas)}: β = {beta:.4f}, {m} moves, acceptance {accept[-1]:.2f}, "
                     f"correlation with the stage's start {corr[-1]:.2f}" + (f" within {modes[-1]} modes" if modes[-1] > 1 else ""))
    x, lp = state[0], state[1]
    if not reason and max(corr, default=0.0) > decorrelation:
        stuck = [i + 1 for i, c in enumerate(corr) if c > decorrelation]
        worst = slowest[int(np.argmax(corr))]
        who = names[worst] if worst < len(names) else f"u[{worst}]"
        within = sorted({budgets[i - 1] for i in stuck})
        reason = (f"the particles did not forget their start within {' or '.join(map(str, within))} moves at stage(s) "
                  f"{', '.join(map(str, stuck))} (largest correlation {max(corr):.2f} > {decorrelation}, of {who})")
        if max(corr) <= floor_90:
            # the stall is within the check's noise: it cannot tell these particles from ones that forgot
            reason += (f"; {n} particles cannot resolve it: over {dim} coordinates particles that forgot their start "
                       f"show a largest correlation above {floor_90:.2f} at one check in ten "
                       f"(about {particles_resolving(decorrelation, dim)} particles resolve {decorrelation})")
    converged = not reason
    length = (f"{leapfrog_steps} leapfrog steps" if leapfrog_steps else
              f"trajectories {HMC_TRAJECTORY_LENGTH:.2f} of the particles' spread long (at most {HMC_MAX_LEAPFROG_STEPS} "
              "leapfrog steps)")
    how = (f"HMC moves of {length}, each move's step the tuned one over a log-uniform factor up to "
           f"{HMC_STEP_SPREAD:g}, with the particles' covariance as inverse mass matrix"
           if log_p_and_grad is not None else
           "random-walk Metropolis moves with the particles' covariance alternating with independence proposals "
           "from their Gaussian")
    return SMCResult(
        chain=x[:, None, :], log_prob=lp[:, None], tau=np.ones(dim), n_steps=int(sum(moves)), burn_in=0, thin=1,
        acceptance_fraction=np.array([float(np.mean(accept)) if accept else 0.0]), converged=converged,
        reason=reason, names=names, seed=seed,
        moves=f"tempered SMC from the split normal: {n} particles, {len(betas)} stages, {how}",
        betas=tuple(betas), stage_moves=tuple(moves), stage_acceptance=tuple(accept), stage_correlation=tuple(corr),
        approximation_pareto_k=float(k_q), stage_step_size=tuple(steps), stage_leapfrog_steps=tuple(trajectory),
        stage_modes=tuple(modes), stage_max_moves=tuple(budgets),
        mode_shares=tuple(float(s) for s in np.bincount(labels) / n) if betas else (),
        correlation_floor=floor)
