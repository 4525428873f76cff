"""A mixture of split normals, one per optimum of a multimodal posterior.

The split normal (:mod:`._split_normal`) stands for the posterior around one optimum. Where the
MAP's starts end at several optima the data support about as well (on measured cycloidal loops:
12 of 21 files, optima 3 to thousands of posterior sd apart and within a few nats), intervals
drawn around one of them do not reach the others. Each optimum gets its own split normal and a
weight by its Laplace evidence, the posterior's mass under that component:

    ``Z_i ≈ p(m_i) / q_i(m_i)``

(``q_i`` normalised, so ``1/q_i(m_i)`` is the component's volume), the weights ``Z_i / Σ Z_j``.
Draws, the normalised density (for importance ratios) and its gradient (for SMC's HMC moves) are
exact for the mixture.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._split_normal import SplitNormal

__all__ = ["SplitNormalMixture", "evidence_log_weights"]


def evidence_log_weights(log_posterior_at_modes, log_q_at_modes) -> np.ndarray:
    """Normalised log weights of components whose modes have (unnormalised) log posterior
    ``log_posterior_at_modes`` and normalised component log density ``log_q_at_modes`` there:
    each the log of the posterior mass the component stands for, ``log p(m_i) − log q_i(m_i)``."""
    log_z = np.asarray(log_posterior_at_modes, float) - np.asarray(log_q_at_modes, float)
    if not np.all(np.isfinite(log_z)):
        raise ValueError(f"a component's evidence is not finite: log Z = {log_z}")
    return log_z - np.logaddexp.reduce(log_z)


@dataclass(frozen=True)
class SplitNormalMixture:
    """``components`` (the first: the MAP's) with normalised ``log_weights``."""

    components: tuple[SplitNormal, ...]
    log_weights: np.ndarray

    def __post_init__(self):
        if len(self.components) != len(self.log_weights):
            raise ValueError(f"{len(self.components)} components but {len(self.log_weights)} weights")
        if not np.isclose(np.logaddexp.reduce(self.log_weights), 0.0, atol=1e-9):
            raise ValueError("the mixture's weights do not sum to 1")

    @property
    def weights(self) -> np.ndarray:
        return np.exp(self.log_weights)

    @property
    def main(self) -> SplitNormal:
        """The MAP's component (its half-axes are what a single split normal reports)."""
        return self.components[0]

    def draw(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """``size`` draws (size, dim): a multinomial count per component, shuffled."""
        counts = rng.multinomial(size, self.weights)
        x = np.concatenate([c.draw(rng, int(k)) for c, k in zip(self.components, counts)])
        return x[rng.permutation(size)]

    def _component_log_densities(self, x: np.ndarray) -> np.ndarray:
        return np.stack([w + c.log_density(x) for c, w in zip(self.components, self.log_weights)])

    def log_density(self, x: np.ndarray) -> np.ndarray:
        """Normalised log density of rows of ``x`` (n, dim)."""
        return np.logaddexp.reduce(self._component_log_densities(x), axis=0)

    def grad_log_density(self, x: np.ndarray) -> np.ndarray:
        """Gradient of :meth:`log_density` at rows of ``x``: the components' gradients weighted by
        their responsibilities there."""
        parts = self._component_log_densities(x)
        resp = np.exp(parts - np.logaddexp.reduce(parts, axis=0))
        return sum(r[:, None] * c.grad_log_density(x) for r, c in zip(resp, self.components))
