"""Model selection for closing the loop: does an extension earn its keep?

Each fit is scored twice, pointwise (one term per sample: the AR(1) one-step conditional
density of its innovation, with σ floored by the encoder's quantisation, see
``FitProblem.pointwise_log_likelihood``):

- **PSIS-LOO** on draws from the fit's Laplace approximation, importance-corrected towards the
  posterior (``arviz_stats.loo_approximate_posterior``: the log posterior and the Laplace
  density of every draw), with each observation's Pareto k checked against
  ``good_k = min(1 − 1/log10 S, 0.7)`` for S draws.
- **Linearised LOO** (deterministic, always finite): the model linearised at its MAP — the
  Jacobian of the whitened residuals with respect to every mean parameter, the prior as
  pseudo-observations — gives each sample's leverage h_i, and the leave-one-out predictive of
  a linear-Gaussian model in closed form: residual w_i/(1 − h_i), variance σ_i²/(1 − h_i), i.e.
  ``log p(y_i | y_−i) = ℓ(w_i/√(1 − h_i)) + ½ log(1 − h_i)``. Its sum is ℓ(θ̂) − Σh_i to first
  order: an information criterion with the effective number of parameters Σh_i.

The rule (:func:`compare`): PSIS-LOO decides when every observation's k is good in both
fits; otherwise — a Laplace approximation far from the posterior (weakly identified,
curved directions: its draws are what blew ΔELPD up to −10⁹) or draws whose likelihood is not
finite — the linearised LOO decides, for both fits, and the comparison says why.
"""

import warnings
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

#: the two criteria, as diagnose.json names them
PSIS = "psis-loo"
LINEARISED = "linearised-loo"

_H_MAX = 1.0 - 1e-9  # leverage cap (a sample fitted exactly by its own parameter)


@dataclass(frozen=True, eq=False)
class Score:
    """Both pointwise scores of one fit."""

    linearised: np.ndarray  # linearised LOO per sample (always finite)
    psis: np.ndarray | None  # PSIS-LOO per sample; None when it could not be computed
    pareto_k: np.ndarray | None
    good_k: float
    psis_note: str  # why PSIS-LOO is missing, or ""
    lengths: tuple  # samples per run (campaign order)

    @property
    def bad_k(self) -> int:
        return -1 if self.pareto_k is None else int(np.sum(~(self.pareto_k <= self.good_k)))

    @property
    def max_k(self) -> float:
        return float("nan") if self.pareto_k is None or not self.pareto_k.size else float(np.max(self.pareto_k))

    @property
    def psis_ok(self) -> bool:
        return self.psis is not None and self.bad_k == 0 and bool(np.all(np.isfinite(self.psis)))

    def as_dict(self) -> dict:
        return {
            "elpd_linearised_loo": float(np.sum(self.linearised)),
            "elpd_psis_loo": None if self.psis is None else float(np.sum(self.psis)),
            "pareto_k_max": None if self.pareto_k is None else self.max_k,
            "pareto_k_bad": None if self.pareto_k is None else self.bad_k,
            "good_k": self.good_k,
            "psis_note": self.psis_note,
        }


@dataclass(frozen=True)
class Comparison:
    delta: float  # ΔELPD of the extension (after − before)
    se: float
    criterion: str  # PSIS or LINEARISED
    reason: str  # why that criterion decided

    def as_dict(self) -> dict:
        return {"delta_elpd": self.delta, "delta_elpd_se": self.se, "criterion": self.criterion,
                "criterion_reason": self.reason}


#: contiguous blocks per run for the standard error of ΔELPD
SE_BLOCKS_PER_RUN = 20


def _difference(a: np.ndarray, b: np.ndarray, lengths) -> tuple[float, float]:
    """ΔELPD = Σ (b − a) and its standard error from contiguous blocks of each run (batch
    means): neighbouring samples' terms are correlated wherever a misfit is structured, and
    the per-sample formula √(N var) would count each structure as many independent wins."""
    diff = b - a
    blocks = []
    for part in np.split(diff, np.cumsum(lengths)[:-1]):
        blocks += np.array_split(part, min(SE_BLOCKS_PER_RUN, len(part)))
    sums = np.array([x.sum() for x in blocks])
    sizes = np.array([len(x) for x in blocks], float)
    mean = float(np.sum(diff)) / max(len(diff), 1)
    n = len(sums)
    var = float(np.sum((sums - sizes * mean) ** 2)) * n / max(n - 1, 1)
    return float(np.sum(diff)), float(np.sqrt(var))


def _why_not(name: str, s: Score) -> str:
    if s.psis is None:
        return f"{name}: {s.psis_note or 'not computed'}"
    return f"{name}: Pareto k > {s.good_k:.2f} at {s.bad_k} of {len(s.psis)} samples (max k {s.max_k:.2g})"


def compare(before: Score, after: Score) -> Comparison:
    """ΔELPD ± SE of ``after`` against ``before`` by the rule of the module docstring; finite."""
    if before.psis_ok and after.psis_ok:
        d, se = _difference(before.psis, after.psis, before.lengths)
        if np.isfinite(d) and np.isfinite(se):
            return Comparison(d, se, PSIS, f"Pareto k ≤ {min(before.good_k, after.good_k):.2f} at every sample in both fits")
    reasons = [_why_not(name, s) for name, s in (("before", before), ("after", after)) if not s.psis_ok]
    d, se = _difference(before.linearised, after.linearised, before.lengths)
    return Comparison(d, se, LINEARISED, "PSIS-LOO unreliable — " + "; ".join(reasons or ["non-finite ΔELPD"]))


# --------------------------------------------------------------------------- linearised LOO
def leverage(jac: np.ndarray, n_data: int, design: np.ndarray | None) -> np.ndarray:
    """Leverage h_i of each of the first ``n_data`` rows of a linearised model: ``jac`` the
    Jacobian of the profiled whitened residuals in the non-linear parameters (data rows, then
    the prior's pseudo-residual rows, which add its precision), ``design`` the whitened design of
    the linear parameters (flat prior; None when there are none). The linear parameters' hat
    matrix plus that of the non-linear block with them projected out (the profiled Jacobian is
    that projection), capped below 1."""
    h = np.zeros(n_data)
    if jac.size:
        data = jac[:n_data]
        h += np.sum(data * _solve_psd(jac.T @ jac, data.T).T, axis=1)
    if design is not None and design.size:
        a = design.T @ design
        a = a + 1e-10 * np.trace(a) / a.shape[0] * np.eye(a.shape[0])
        h += np.sum(design * _solve_psd(a, design.T).T, axis=1)
    return np.clip(h, 0.0, _H_MAX)


def linearised_loo(problem, u) -> np.ndarray:
    """Linearised leave-one-out log predictive density per sample (all runs, campaign order):
    each sample's term ℓ(w_i/√(1 − h_i)) + ½ log(1 − h_i) with the leverage of :func:`leverage`.
    For a linear model with Gaussian noise of known scale this is exact leave-one-out."""
    from ..fit._map import _laplace_parts  # compiled by the MAP fit for this problem's shape

    jac, _, rho, _, (white, scales, wx) = _laplace_parts(problem, jnp.asarray(u))
    jac = np.asarray(jac)
    white, scales = [np.asarray(w) for w in problem.split_runs(white)], problem.split_runs(scales)
    n_data = sum(len(w) for w in white)
    design = np.asarray(wx) if problem.n_linear else None
    h = leverage(jac, n_data, design)
    hs = np.split(h, np.cumsum([len(w) for w in white])[:-1])
    ll = problem._pointwise([jnp.asarray(w / np.sqrt(1.0 - hr)) for w, hr in zip(white, hs)], scales, rho)
    return np.concatenate([np.asarray(v) + 0.5 * np.log1p(-hr) for v, hr in zip(ll, hs)])


def _solve_psd(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b for a symmetric positive semi-definite a (pseudo-inverse on its null space)."""
    vals, vecs = np.linalg.eigh(0.5 * (a + a.T))
    keep = vals > 1e-12 * max(float(vals[-1]), 1e-300)
    inv = np.where(keep, 1.0 / np.where(keep, vals, 1.0), 0.0)
    return vecs @ (inv[:, None] * (vecs.T @ b))


# --------------------------------------------------------------------------- PSIS-LOO
@eqx.filter_jit
def _draw_terms(problem, u_batch):
    def one(u):
        return jnp.concatenate(problem.pointwise_log_likelihood(u)), problem.log_density(u)

    return jax.lax.map(one, u_batch)


def psis_loo(problem, map_result, draws: int, seed: int):
    """(PSIS-LOO per sample, Pareto k per sample, good_k, note) from ``draws`` Laplace draws,
    corrected towards the posterior. Draws with a non-finite likelihood have posterior density
    zero and get no weight; with fewer than half the draws left the result is None."""
    from arviz_base import from_dict
    from arviz_stats import loo_approximate_posterior
    from scipy.stats import multivariate_normal

    from ..sample import good_k as good_k_for, importance_pareto_k

    good_k = good_k_for(draws)
    rng = np.random.default_rng(seed)
    cov = 0.5 * (map_result.cov + map_result.cov.T)
    u = rng.multivariate_normal(map_result.u, cov, size=draws, method="eigh")
    ll, log_p = (np.asarray(x) for x in _draw_terms(problem, jnp.asarray(u)))
    finite = np.all(np.isfinite(ll), axis=1) & np.isfinite(log_p)
    if finite.sum() < max(draws // 2, 10):
        return None, None, good_k, f"{draws - int(finite.sum())} of {draws} Laplace draws have a non-finite likelihood"
    u, ll, log_p = u[finite], ll[finite], log_p[finite]
    log_q = np.asarray(multivariate_normal(mean=map_result.u, cov=cov, allow_singular=True).logpdf(u))
    # the approximation itself first: when the posterior/Laplace ratios have a bad Pareto k the
    # draws do not stand for the posterior, and no observation's k can be good
    k_q = importance_pareto_k(log_p, log_q)
    if not float(k_q) <= good_k:
        k_text = f"{float(k_q):.2g}" if np.isfinite(k_q) else "undefined"
        return None, None, good_k, (f"the Laplace draws do not represent the posterior (Pareto k of the "
                                    f"posterior/Laplace density ratios {k_text}, above {good_k:.2f})")
    tree = from_dict({"posterior": {"u0": u[:, 0][None, :]}, "log_likelihood": {"y": ll[None, :, :]}})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the Pareto k are checked by the selection rule
        res = loo_approximate_posterior(tree, log_p[None, :], np.asarray(log_q)[None, :], pointwise=True, var_name="y")
    elpd_i = np.asarray(res.elpd_i).reshape(-1)
    k = np.asarray(res.pareto_k).reshape(-1)
    good_k = float(getattr(res, "good_k", good_k))
    if not np.all(np.isfinite(elpd_i)):
        return None, k, good_k, "PSIS-LOO gave non-finite pointwise values"
    return elpd_i, k, good_k, ""


def score(problem, map_result, draws: int, seed: int) -> Score:
    lin = linearised_loo(problem, map_result.u)
    try:
        psis, k, good_k, note = psis_loo(problem, map_result, draws, seed)
    except (ValueError, np.linalg.LinAlgError) as err:  # a degenerate draw set
        psis, k, good_k, note = None, None, 0.7, f"PSIS-LOO failed: {err}"
    return Score(linearised=lin, psis=psis, pareto_k=k, good_k=good_k, psis_note=note,
                 lengths=tuple(len(y) for y in problem.y))
