"""The paper's generalised polynomial H (Eqs. 26–28), fitted with uncertainty.

K_d = H(TE_z(θ_k), τ, v) = τ / P(τ, v): the TE at one output position (or its revolution mean,
Eq. 28) as a polynomial in load torque τ and output speed v over the operating grid,

    P(τ, v) = Σ_{i ≤ p, j ≤ q} c_ij (τ / τ_s)^i (v / v_s)^j,

with τ_s, v_s scales (the grid's largest torque and speed) so the coefficients share the unit
of the TE. The fit is Bayesian linear regression: flat prior on c, unknown noise scale σ with
prior ∝ 1/σ, optional relative weights; the posterior of c is a multivariate Student t with
n − k degrees of freedom around the least-squares solution.
"""

from dataclasses import dataclass

import numpy as np

from .._errors import InputError


def _terms(degree_torque: int, degree_speed: int) -> tuple[tuple[int, int], ...]:
    return tuple((i, j) for i in range(degree_torque + 1) for j in range(degree_speed + 1))


@dataclass(frozen=True)
class PolynomialFit:
    """Posterior of the coefficients of P(τ, v) (in ``unit``): ``mean`` and ``scale_matrix``
    (the t distribution's scale, s²(XᵀWX)⁻¹), ``dof`` degrees of freedom; ``sigma`` the
    residual sd (``unit``) of a point of weight 1; ``n_points`` the grid points fitted."""

    terms: tuple[tuple[int, int], ...]
    torque_scale_Nm: float
    speed_scale_rpm: float
    mean: np.ndarray
    scale_matrix: np.ndarray
    dof: int
    sigma: float
    n_points: int
    unit: str

    @property
    def degrees(self) -> tuple[int, int]:
        """(degree in torque, degree in speed)."""
        return max(i for i, _ in self.terms), max(j for _, j in self.terms)

    def design(self, torque_Nm, speed_rpm) -> np.ndarray:
        """Design matrix (points, terms) at paired 1-D ``torque_Nm`` and ``speed_rpm``."""
        return design_matrix(torque_Nm, speed_rpm, self.terms, self.torque_scale_Nm, self.speed_scale_rpm)

    def predict(self, torque_Nm, speed_rpm) -> np.ndarray:
        """P(τ, v) at the posterior mean of the coefficients (``unit``)."""
        return self.design(torque_Nm, speed_rpm) @ self.mean

    def coefficient_draws(self, n_draws: int, seed: int) -> np.ndarray:
        """(n_draws, terms) draws of the coefficients from their multivariate t posterior."""
        rng = np.random.default_rng(seed)
        z = rng.multivariate_normal(np.zeros(len(self.terms)), self.scale_matrix, size=n_draws, method="eigh")
        w = rng.chisquare(self.dof, size=n_draws) / self.dof
        return self.mean + z / np.sqrt(w)[:, None]

    def predict_draws(self, torque_Nm, speed_rpm, n_draws: int, seed: int) -> np.ndarray:
        """(n_draws, points) of P(τ, v) over the coefficients' posterior (``unit``)."""
        return self.coefficient_draws(n_draws, seed) @ self.design(torque_Nm, speed_rpm).T

    def term_names(self) -> list[str]:
        """Each term as text, e.g. ``(τ/380 N·m)^1 (v/10 rpm)^2``."""
        names = []
        for i, j in self.terms:
            parts = ([f"(τ/{self.torque_scale_Nm:g} N·m)^{i}"] if i else []) + \
                    ([f"(v/{self.speed_scale_rpm:g} rpm)^{j}"] if j else [])
            names.append(" ".join(parts) or "1")
        return names

    def coefficients(self, n_draws: int = 4000, seed: int = 0) -> list[dict]:
        """One entry per term: ``{"term", "i", "j", "mean", "sd", "hdi95", "unit"}``."""
        draws = self.coefficient_draws(n_draws, seed)
        lo, hi = np.percentile(draws, [2.5, 97.5], axis=0)  # symmetric posterior: HDI = central
        sd = np.sqrt(np.diag(self.scale_matrix) * self.dof / (self.dof - 2)) if self.dof > 2 else np.full(len(self.terms), np.inf)
        return [{"term": name, "i": i, "j": j, "mean": float(m), "sd": float(s), "hdi95": [float(a), float(b)],
                 "unit": self.unit}
                for name, (i, j), m, s, a, b in zip(self.term_names(), self.terms, self.mean, sd, lo, hi)]


def design_matrix(torque_Nm, speed_rpm, terms, torque_scale_Nm: float, speed_scale_rpm: float) -> np.ndarray:
    """Columns (τ/τ_s)^i (v/v_s)^j for each term (i, j), rows the paired 1-D points."""
    t = np.asarray(torque_Nm, float) / torque_scale_Nm
    v = np.asarray(speed_rpm, float) / speed_scale_rpm
    return np.stack([t**i * v**j for i, j in terms], axis=-1)


def fit_polynomial(torque_Nm, speed_rpm, value, *, degree_torque: int = 2, degree_speed: int = 2,
                   unit: str = "arcmin", weights=None) -> PolynomialFit:
    """Fit P(τ, v) of degrees (``degree_torque``, ``degree_speed``) to ``value`` (``unit``) at
    paired 1-D ``torque_Nm``, ``speed_rpm``; ``weights``: relative inverse variances (default
    equal). InputError on mismatched, non-finite or too few points (needs ≥ terms + 3 for a
    posterior with finite variance)."""
    t, v, y = (np.asarray(a, float).ravel() for a in (torque_Nm, speed_rpm, value))
    if not (t.size == v.size == y.size):
        raise InputError(f"polynomial fit: torque ({t.size}), speed ({v.size}) and value ({y.size}) must have one length")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v)) and np.all(np.isfinite(y))):
        raise InputError("polynomial fit: non-finite torque, speed or value")
    if min(degree_torque, degree_speed) < 0:
        raise InputError(f"polynomial fit: degrees must be ≥ 0, got ({degree_torque}, {degree_speed})")
    terms = _terms(degree_torque, degree_speed)
    if y.size < len(terms) + 3:
        raise InputError(f"polynomial fit: {y.size} points for {len(terms)} coefficients; need at least "
                         f"{len(terms) + 3} (a grid of more torques and speeds, or lower degrees)")
    w = np.ones_like(y) if weights is None else np.asarray(weights, float).ravel()
    if w.size != y.size or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise InputError("polynomial fit: weights must be positive, finite and one per point")
    t_s, v_s = float(np.max(np.abs(t))), float(np.max(np.abs(v)))
    if t_s == 0 or v_s == 0:
        raise InputError("polynomial fit: torque and speed must not all be zero")
    x = design_matrix(t, v, terms, t_s, v_s)
    sw = np.sqrt(w)
    xw, yw = x * sw[:, None], y * sw
    if np.linalg.matrix_rank(xw) < len(terms):
        raise InputError(f"polynomial fit: the grid cannot identify degrees ({degree_torque}, {degree_speed}); "
                         f"it needs more than {degree_torque} torques and {degree_speed} speeds")
    coef, *_ = np.linalg.lstsq(xw, yw, rcond=None)
    dof = y.size - len(terms)
    s2 = float(np.sum((yw - xw @ coef) ** 2) / dof)
    scale = s2 * np.linalg.inv(xw.T @ xw)
    return PolynomialFit(terms, t_s, v_s, coef, 0.5 * (scale + scale.T), dof, float(np.sqrt(s2)), int(y.size), unit)


def bic(fit: PolynomialFit) -> float:
    """Bayesian information criterion of a fit: n·ln(RSS/n) + k·ln(n) (lower is better)."""
    n, k = fit.n_points, len(fit.terms)
    rss = max(fit.sigma**2 * fit.dof, 1e-300)
    return float(n * np.log(rss / n) + k * np.log(n))


def select_polynomial(torque_Nm, speed_rpm, value, *, max_degree_torque: int = 2, max_degree_speed: int = 3,
                      unit: str = "arcmin", weights=None) -> PolynomialFit:
    """The fit of lowest BIC over degrees 1..``max_degree_torque`` × 1..``max_degree_speed`` that
    the points can carry (at least terms + 3 points, each degree below the number of distinct
    torques / speeds)."""
    n_t, n_v = len(np.unique(np.asarray(torque_Nm, float))), len(np.unique(np.asarray(speed_rpm, float)))
    n = np.asarray(value).size
    candidates = [(p, q) for p in range(1, max_degree_torque + 1) for q in range(1, max_degree_speed + 1)
                  if p < n_t and q < n_v and n >= (p + 1) * (q + 1) + 3]
    if not candidates:
        raise InputError(f"polynomial fit: {n} points over {n_t} torques × {n_v} speeds are too few for any "
                         f"polynomial of degree ≥ 1 in both")
    fits = [fit_polynomial(torque_Nm, speed_rpm, value, degree_torque=p, degree_speed=q, unit=unit, weights=weights)
            for p, q in candidates]
    return min(fits, key=bic)
