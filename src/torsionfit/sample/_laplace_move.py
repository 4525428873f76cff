"""An independence Metropolis–Hastings move for emcee, proposing from the MAP's Laplace
approximation.

Each walker proposes x' from a multivariate Student-t centred at the MAP with the Laplace
covariance (regularised, scaled by ``scale``²) and ``dof`` degrees of freedom, independently
of where it is, and accepts with probability min(1, p(x') q(x) / p(x) q(x')). That is a valid
Metropolis–Hastings kernel for any fixed q (the proposal never adapts to the chain), so the
posterior is left invariant whatever the quality of the Laplace approximation; the quality
only sets the efficiency. Where the Laplace approximation is good — the usual case for a loop of
thousands of samples — a walker jumps across the whole posterior in one accepted step, and the
integrated autocorrelation time falls from ~44 steps (DE + stretch) to ~4–6 (``benchmarks/bench_moves.py``
on ``benchmarks/benches/full_fit_2k.toml``). The t tails (heavier than the Gaussian) and the scale
> 1 keep the importance ratio bounded where the posterior is wider than the approximation;
where it is far off, acceptance falls and the ensemble moves of the mixture do the work.

A move whose proposals are almost never accepted still takes its share of the steps: on a
measured loop that the base model misses (``examples/cycloidal-jv``, ``scripts/measured_fits.py``)
the Laplace proposals were accepted 0.3–0.4 % of the time, and with the move kept (commit 4550bc2) the chains
needed 49 500 (initial-pos1) and 29 500 (initial-pos5) steps, τ_max 981 and 584; retired at
step 500: 32 500 and 14 000 steps, τ_max 642 and 279. So the move counts its own acceptances, and ``retire()`` hands
its share of the steps to a differential-evolution move for the rest of the run
(``run_sampler`` does once, at its first check, when the acceptance is below
:data:`RETIRE_BELOW`). Switching kernels once, at a fixed step, by a rule on the past keeps
the chain valid: each kernel leaves the posterior invariant, and after the switch the chain
is homogeneous.
"""

import emcee
import numpy as np

#: ``run_sampler`` retires the move when fewer of its proposals than this were accepted in
#: the first block (measured: ~0.5 on the benchmark loop, 0.003–0.004 on the measured loops)
RETIRE_BELOW = 0.05


class LaplaceMove(emcee.moves.MHMove):
    """Independence proposal t_ν(u_map, scale²·cov) for every walker (u space)."""

    def __init__(self, u_map, cov, scale: float = 1.2, dof: float = 8.0):
        u_map = np.asarray(u_map, dtype=float)
        cov = np.asarray(cov, dtype=float)
        if cov.shape != (u_map.size, u_map.size):
            raise ValueError(f"cov must be {u_map.size}×{u_map.size}, got {cov.shape}")
        if not (scale > 0 and dof > 0):
            raise ValueError(f"scale and dof must be positive, got {scale}, {dof}")
        self.u_map = u_map
        self.chol = scale * np.linalg.cholesky(cov)
        self.dof = float(dof)
        self.proposed = 0  # walker proposals made (not counted once retired)
        self.accepted = 0  # of which accepted
        self.retired = False
        self._fallback = emcee.moves.DEMove()
        super().__init__(self._propose, ndim=u_map.size)

    @property
    def acceptance(self) -> float:
        """Fraction of this move's proposals accepted so far (NaN before the first)."""
        return self.accepted / self.proposed if self.proposed else float("nan")

    def retire(self) -> None:
        """From now on, propose as a differential-evolution move."""
        self.retired = True

    def propose(self, model, state):
        if self.retired:
            return self._fallback.propose(model, state)
        state, accepted = super().propose(model, state)
        self.proposed += int(accepted.size)
        self.accepted += int(np.sum(accepted))
        return state, accepted

    def counters(self) -> dict:
        """What a resumed run needs: proposed, accepted, retired (ints)."""
        return {"laplace_proposed": self.proposed, "laplace_accepted": self.accepted,
                "laplace_retired": int(self.retired)}

    def restore(self, attrs) -> None:
        """Counters and state from :meth:`counters` (missing keys: a fresh move)."""
        self.proposed = int(attrs.get("laplace_proposed", 0))
        self.accepted = int(attrs.get("laplace_accepted", 0))
        self.retired = bool(attrs.get("laplace_retired", 0))

    def log_q(self, coords) -> np.ndarray:
        """log proposal density of each row of ``coords``, up to a constant."""
        z = np.linalg.solve(self.chol, (np.atleast_2d(coords) - self.u_map).T)
        m = np.sum(z * z, axis=0)
        return -0.5 * (self.dof + self.u_map.size) * np.log1p(m / self.dof)

    def _propose(self, coords, random):
        n, d = coords.shape
        z = random.standard_normal((n, d))
        g = random.chisquare(self.dof, n) / self.dof
        proposal = self.u_map + (z @ self.chol.T) / np.sqrt(g)[:, None]
        # MHMove's factor: ln q(x) − ln q(x'), the Hastings correction of an independence move
        return proposal, self.log_q(coords) - self.log_q(proposal)
