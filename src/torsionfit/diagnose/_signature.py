"""Residual signatures as regression tests on whitened residuals.

An effect's signature is a small set of regressors (per run, the same columns across runs)
that its missing physics would leave in the residual. Both the residuals and the regressors
are whitened with the fit's own noise model (AR(1), per-sample scales) and the regressors are
made orthogonal to the fit's linear terms (offsets, drift, harmonics), so under "the model is
right" the explained sum of squares Δχ² is χ² with k degrees of freedom. The p-value is the
threshold with a meaning; the effect size is the fraction of the residual variance explained.
A residual that moves in jumps (stick-slip steps, outliers) inflates the noise that test reads
and hides what is there; robust views are tested winsorised as well (:func:`regression_evidence`).
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


#: Huber's threshold (noise sds) for the winsorised test: 95 % of the least-squares test's
#: efficiency on Gaussian noise, and a jump weighs no more than this
HUBER_SDS = 1.345


def _huber_residual(w: np.ndarray, q: np.ndarray, iterations: int = 100) -> np.ndarray:
    """The residual of ``w`` after a Huber regression (threshold HUBER_SDS) on the orthonormal
    columns ``q``, by iteratively reweighted least squares: the nuisance refitted with each jump
    weighing no more than HUBER_SDS, so that the clipped residual is orthogonal to every column.
    The weights lie in (0, 1] and ``q`` is orthonormal: the normal equations are well posed."""
    if not q.shape[1]:
        return w
    r = w - q @ (q.T @ w)
    for _ in range(iterations):
        weight = HUBER_SDS / np.maximum(np.abs(r), HUBER_SDS)
        qw = q * weight[:, None]
        new = w - q @ np.linalg.solve(qw.T @ q, qw.T @ w)
        if np.max(np.abs(new - r)) < 1e-6 * HUBER_SDS:
            return new
        r = new
    return r


def _winsorised_test(w: np.ndarray, x: np.ndarray, q: np.ndarray, lengths: list) -> tuple[np.ndarray, float, float]:
    """(coefficients, Δχ², explained share) of the columns ``x`` (nuisance projected out) on the
    whitened residual ``w`` after a Huber regression on the nuisance (orthonormal columns ``q``;
    ``lengths``: the runs' sample counts, in order), clipped at ±HUBER_SDS: the
    least-squares test on a winsorised residual (a score test of the Huber M-estimator), in
    units of the winsorised noise's variance — read from the residual's increments, per run, as
    the variogram reads the noise (a smooth misfit hardly moves them; the jumps do, so they count
    there at their clipped weight)."""
    r = _huber_residual(w, q)
    psi = np.clip(r, -HUBER_SDS, HUBER_SDS)
    bounds = np.cumsum([0, *lengths])
    steps = np.concatenate([np.diff(r[a:b]) / np.sqrt(2.0) for a, b in zip(bounds[:-1], bounds[1:])])
    noise_var = float(np.mean(np.clip(steps, -HUBER_SDS, HUBER_SDS) ** 2))
    coef, *_ = np.linalg.lstsq(x, psi, rcond=None)
    fitted = x @ coef
    explained = float(fitted @ fitted)
    return coef, explained / max(noise_var, 1e-300), explained / max(float(psi @ psi), 1e-300)


def _test(runs, columns, robust: bool):
    """(coefficients, Δχ², dof, explained share) of one test, or None when the regressors vanish
    against the nuisance (see :func:`regression_evidence`)."""
    ws, xs, shared, local = [], [], [], []
    for run, cols in zip(runs, columns):
        n = len(run.residual)
        ws.append(run.whiten(run.residual, robust))
        xs.append(run.whiten(np.asarray(cols, float).reshape(n, -1), robust))
        # the winsorised test's nuisance has the fit's physics too, one column per parameter over the runs
        design = np.concatenate([run.design, run.physics_design], axis=1) if robust else run.design
        shared.append(run.whiten(design, robust) if design.size else np.zeros((n, design.shape[1])))
        own = run.local_design
        local.append(run.whiten(own, robust) if own is not None and own.size else np.zeros((n, 0)))
    if len({s.shape[1] for s in shared}) > 1:
        raise ValueError(f"the runs tested together have designs of different widths "
                         f"{sorted({s.shape[1] for s in shared})}; a run's own columns belong in local_design")
    w = np.concatenate(ws)
    x = np.concatenate(xs, axis=0)
    nuisance = np.concatenate([np.concatenate(shared, axis=0), _block_diagonal(local)], axis=1)
    before = np.linalg.norm(x, axis=0)
    q = _basis(nuisance) if nuisance.shape[1] else np.zeros((len(w), 0))
    x = x - q @ (q.T @ x)
    x = x[:, np.linalg.norm(x, axis=0) > _VANISHED * np.maximum(before, 1e-300)]
    if not x.shape[1]:
        return None
    k = int(np.linalg.matrix_rank(x))
    if robust:
        coef, stat, share = _winsorised_test(w, x, q, [len(a) for a in ws])
    else:
        coef, *_ = np.linalg.lstsq(x, w, rcond=None)
        fitted = x @ coef
        stat = float(fitted @ fitted)
        share = stat / max(float(w @ w), 1e-300)
    return coef, stat, k, share


def regression_evidence(effect: str, runs, columns, description: str, details=None) -> Evidence:
    """Δχ² of ``columns`` (list per run: (N_r, k) arrays, or None to skip a run) on the whitened
    residuals of ``runs``, after projecting out the nuisance: the fit's linear design jointly over
    the runs tested — a parameter shared by runs (the TE zero, the kinematic harmonics) is one
    column for all of them; projected run by run it would remove every difference between the
    runs' levels, e.g. a TE level that changes with speed — and each run's ``local_design``.

    Robust views (``RunView.robust``) are tested twice: by least squares against the mean-square
    variogram's noise, and winsorised against the noise read from median increments with the fit's
    physics among the nuisance (robust to jumps); the better p-value counts, Bonferroni over the
    two. Each test has the other's blind spot: the winsorised one discounts a large misfit on a few
    samples (a torque offset shows at the gap crossings), the least-squares one a smooth effect
    behind jumps. ``details["test"]`` says which one counted, ``details["log10_p_by_test"]`` each
    test's own log10 p (before the correction over the two)."""
    tested = [(r, c) for r, c in zip(runs, columns) if c is not None]
    if not tested:
        return Evidence(effect, 0.0, 0, 0.0, 0.0, description + " (not applicable: no run shows it)", details or {})
    views, cols = zip(*tested)
    try:
        found = {"least-squares": _test(views, cols, robust=False)}
        if all(r.robust for r in views):
            found["winsorised"] = _test(views, cols, robust=True)
    except ValueError as error:
        raise ValueError(f"{effect}: {error}") from None
    found = {name: t for name, t in found.items() if t is not None}
    if not found:
        return Evidence(effect, 0.0, 0, 0.0, 0.0, description + " (regressors vanish)", details or {})
    p = {name: log10_chi2_sf(t[1], t[2]) for name, t in found.items()}
    name = min(p, key=p.get)
    coef, stat, k, share = found[name]
    out = dict(details or {})
    out["coefficients"] = [float(c) for c in coef]
    out["test"] = name
    out["log10_p_by_test"] = {n: float(v) for n, v in p.items()}
    return Evidence(effect, stat, k, _over_tests(p[name], len(found)), share, description, out)


def _over_tests(log10_p: float, n_tests: int) -> float:
    """The better of ``n_tests`` tests' log10 p, Bonferroni over them (at most p = 1)."""
    return min(0.0, log10_p + float(np.log10(n_tests)))


def least_squares_log10_p(ev: Evidence) -> float:
    """``ev``'s log10 p with its least-squares test in place of the pair it was counted from
    (:func:`regression_evidence`), the corrections applied to it since (searches over shapes
    or orders) kept; ``ev.log10_p`` where least squares was its only test."""
    by_test = ev.details.get("log10_p_by_test", {})
    if "least-squares" not in by_test or len(by_test) < 2:
        return ev.log10_p
    return ev.log10_p - _over_tests(min(by_test.values()), len(by_test)) + by_test["least-squares"]
