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


def regression_evidence(effect: str, runs, columns, description: str, details=None) -> Evidence:
    """Δχ² of ``columns`` (list per run: (N_r, k) arrays, or None to skip a run) on the whitened
    residuals of ``runs``, after projecting out each run's nuisance design."""
    ws, xs = [], []
    for run, cols in zip(runs, columns):
        if cols is None:
            continue
        cols = np.asarray(cols, float).reshape(len(run.residual), -1)
        w = run.whiten(run.residual)
        x = run.whiten(cols)
        nuisance = run.whiten(run.design[:, np.any(run.design != 0, axis=0)]) if run.design.size else None
        if nuisance is not None and nuisance.shape[1]:
            q, _ = np.linalg.qr(nuisance)
            x = x - q @ (q.T @ x)
        ws.append(w)
        xs.append(x)
    if not xs:
        return Evidence(effect, 0.0, 0, 0.0, 0.0, description + " (not applicable: no run shows it)", details or {})
    w = np.concatenate(ws)
    x = np.concatenate(xs, axis=0)
    keep = np.linalg.norm(x, axis=0) > 1e-12 * max(1.0, np.linalg.norm(x))
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
