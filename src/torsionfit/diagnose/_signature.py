"""Residual signatures as regression tests on whitened residuals.

An effect's signature is a small set of regressors (per run, the same columns across runs)
that its missing physics would leave in the residual. Both the residuals and the regressors
are whitened with the fit's own noise model (AR(1), per-sample scales) and the regressors are
made orthogonal to the fit's linear terms (offsets, drift, harmonics), so under "the model is
right" the explained sum of squares Δχ² is χ² with k degrees of freedom. The p-value is the
threshold with a meaning; the effect size is the fraction of the residual variance explained.
"""

from dataclasses import dataclass, field

import numpy as np
from jax.scipy.special import gammaincc


@dataclass(frozen=True)
class Evidence:
    effect: str
    statistic: float  # Δχ² of the signature's regressors on the whitened residuals
    dof: int
    log10_p: float  # log10 of the χ² tail probability (very small numbers stay readable)
    explained: float  # fraction of the whitened residual sum of squares the regressors explain
    description: str
    details: dict = field(default_factory=dict)

    def significant(self, alpha: float) -> bool:
        return self.dof > 0 and self.log10_p < np.log10(alpha)

    def as_dict(self) -> dict:
        return {"statistic": self.statistic, "dof": self.dof, "log10_p": self.log10_p,
                "explained_fraction": self.explained, "description": self.description, **self.details}


def log10_chi2_sf(x: float, k: int) -> float:
    """log10 P(χ²_k > x), accurate far into the tail."""
    if k <= 0:
        return 0.0
    p = float(gammaincc(k / 2.0, max(x, 0.0) / 2.0))
    if p > 1e-300:
        return float(np.log10(p))
    # asymptotic tail: log Γ(s, y) ≈ (s − 1) log y − y − log Γ(s)
    from jax.scipy.special import gammaln

    s, y = k / 2.0, x / 2.0
    return float(((s - 1) * np.log(y) - y - float(gammaln(s))) / np.log(10))


#: a regressor whose norm falls below this share of its norm by projecting out the nuisance
#: columns lies in their span: what is left is rounding, not a direction to test
_VANISHED = 1e-8


def _basis(a: np.ndarray) -> np.ndarray:
    """Orthonormal columns spanning the column space of ``a`` (rank-revealing: a QR of dependent
    columns would add arbitrary directions and project out more than the nuisance)."""
    norms = np.linalg.norm(a, axis=0)
    a = a[:, norms > 0] / norms[norms > 0]
    if not a.shape[1]:
        return a
    u, sv, _ = np.linalg.svd(a, full_matrices=False)
    return u[:, sv > 1e-10 * sv[0]]


def _block_diagonal(blocks: list) -> np.ndarray:
    out = np.zeros((sum(b.shape[0] for b in blocks), sum(b.shape[1] for b in blocks)))
    i = j = 0
    for b in blocks:
        out[i:i + b.shape[0], j:j + b.shape[1]] = b
        i, j = i + b.shape[0], j + b.shape[1]
    return out


def regression_evidence(effect: str, runs, columns, description: str, details=None) -> Evidence:
    """Δχ² of ``columns`` (list per run: (N_r, k) arrays, or None to skip a run) on the whitened
    residuals of ``runs``, after projecting out the nuisance: the fit's linear design jointly over
    the runs tested — a parameter shared by runs (the TE zero, the kinematic harmonics) is one
    column for all of them; projected run by run it would remove every difference between the
    runs' levels, e.g. a TE level that changes with speed — and each run's ``local_design``."""
    ws, xs, shared, local = [], [], [], []
    for run, cols in zip(runs, columns):
        if cols is None:
            continue
        n = len(run.residual)
        ws.append(run.whiten(run.residual))
        xs.append(run.whiten(np.asarray(cols, float).reshape(n, -1)))
        shared.append(run.whiten(run.design) if run.design.size else np.zeros((n, run.design.shape[1])))
        own = run.local_design
        local.append(run.whiten(own) if own is not None and own.size else np.zeros((n, 0)))
    if not xs:
        return Evidence(effect, 0.0, 0, 0.0, 0.0, description + " (not applicable: no run shows it)", details or {})
    if len({s.shape[1] for s in shared}) > 1:
        raise ValueError(f"{effect}: the runs tested together have designs of different widths "
                         f"{sorted({s.shape[1] for s in shared})}; a run's own columns belong in local_design")
    w = np.concatenate(ws)
    x = np.concatenate(xs, axis=0)
    nuisance = np.concatenate([np.concatenate(shared, axis=0), _block_diagonal(local)], axis=1)
    before = np.linalg.norm(x, axis=0)
    if nuisance.shape[1]:
        q = _basis(nuisance)
        x = x - q @ (q.T @ x)
    keep = np.linalg.norm(x, axis=0) > _VANISHED * np.maximum(before, 1e-300)
    x = x[:, keep]
    if not x.shape[1]:
        return Evidence(effect, 0.0, 0, 0.0, 0.0, description + " (regressors vanish)", details or {})
    coef, *_ = np.linalg.lstsq(x, w, rcond=None)
    fitted = x @ coef
    stat = float(fitted @ fitted)
    k = int(np.linalg.matrix_rank(x))
    total = float(w @ w)
    out = dict(details or {})
    out["coefficients"] = [float(c) for c in coef]
    return Evidence(effect, stat, k, log10_chi2_sf(stat, k), stat / max(total, 1e-300), description, out)
