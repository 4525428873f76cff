"""A campaign turned into a fitting problem: parameter layout, priors, noise model, and the
log-density the optimiser and the sampler share.

Layout of the unconstrained vector u: the non-linear physics (one entry per element, in
``model.parameters()`` order), then log s_r per run (noise above the encoder floor), then
logit ρ_r per run with the AR(1) option. The linear parameters (per-run offsets, drift,
kinematic harmonics) are not in u: for any u they are solved by weighted least squares
(variable projection) and, in the log-density, marginalised analytically under a flat
prior, so the sampler sees only the non-linear physics.
"""

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .. import model as m
from .._errors import InputError
from ..io import Campaign, HysteresisRun
from . import _transform as tr
from ._denoise import denoise_torque
from ._prior import build_priors

AR1_MIN_SAMPLES = 200  # the AR(1) default is on for runs at least this dense


@dataclass(frozen=True)
class NoiseOptions:
    """Likelihood options. ``ar1=None`` → on for runs with ≥ 200 samples."""

    ar1: bool | None = None
    student_t_dof: float | None = None  # None: Gaussian; a number: Student-t with that many dof
    denoise_half_width: int | None = None  # torque smoother, samples (None: 0.5 % of the run)


def model_inputs(campaign: Campaign, half_width=None) -> list:
    """Per-run model inputs; hysteresis runs are driven by the denoised measured torque."""
    out = []
    for run in campaign.runs:
        if isinstance(run, HysteresisRun):
            out.append(m.hysteresis_input(run.time_s, denoise_torque(run.torque_Nm, half_width)))
        else:
            out.append(m.te_input(run.output_angle_rad, run.torque_Nm, run.speed_rpm, run.direction, run.time_s))
    return out


def observed(campaign: Campaign) -> list[np.ndarray]:
    return [np.asarray(r.angle_rad if isinstance(r, HysteresisRun) else r.te_rad, float) for r in campaign.runs]


class FitProblem:
    """Everything the fit needs, with pure functions of u (jit/vmap-able)."""

    def __init__(self, campaign: Campaign, model: m.CampaignModel, noise: NoiseOptions = NoiseOptions()):
        kinds = tuple(r.kind for r in campaign.runs)
        if model.run_kinds != kinds:
            raise ValueError(f"model is for runs {model.run_kinds}, campaign has {kinds}")
        if not campaign.runs:
            raise InputError("campaign has no runs to fit")
        for r in campaign.runs:
            if len(r) < 10:
                raise InputError(f"run {r.name!r}: {len(r)} samples; a fit needs at least 10")
            if isinstance(r, HysteresisRun):
                span = float(np.ptp(r.torque_Nm))
                if not span > 0.05 * campaign.reducer.rated_torque_Nm:
                    raise InputError(
                        f"run {r.name!r}: torque spans {span:.3g} N·m, under 5 % of the rated "
                        f"{campaign.reducer.rated_torque_Nm:g} N·m; a run that never loads cannot be fitted"
                    )
        self.campaign = campaign
        self.model = model
        self.noise = noise
        self.inputs = model_inputs(campaign, noise.denoise_half_width)
        self.y = [jnp.asarray(v) for v in observed(campaign)]
        self.n_runs = len(self.y)
        params = model.parameters()
        self.physics = tuple(p for p in params if not p.linear)
        self.linear = tuple(p for p in params if p.linear)
        priors = build_priors(params, campaign)
        self.prior_mean = np.concatenate([np.full(p.size, priors[p.name][0]) for p in self.physics])
        self.prior_sd = np.concatenate([np.full(p.size, priors[p.name][1]) for p in self.physics])
        self.n_physics = int(sum(p.size for p in self.physics))
        self.n_linear = int(sum(p.size for p in self.linear))
        floor = campaign.instrument.angle_floor_rad
        self.floors = np.array([floor if floor else 0.0 for _ in campaign.runs])
        self.ar1 = np.array([
            (len(r) >= AR1_MIN_SAMPLES) if noise.ar1 is None else bool(noise.ar1) for r in campaign.runs
        ])
        self.n_ar1 = int(self.ar1.sum())
        self.dim = self.n_physics + self.n_runs + self.n_ar1
        # noise priors: s_r log-normal around a tenth of the run's angle range (wide), ρ logit-normal
        ranges = np.array([max(float(np.ptp(np.asarray(v))), 1e-9) for v in self.y])
        self.noise_prior_mean = np.log(1e-2 * ranges)
        self.noise_prior_sd = 3.0
        self._design = self._design_matrices()

    # --- parameter layout ------------------------------------------------------------------
    def names(self) -> list[str]:
        """Names of the entries of u (physics on their natural scale, noise as s_r, ρ_r)."""
        out = []
        for p in self.physics:
            out += [p.name] if p.size == 1 else [f"{p.name}[{i}]" for i in range(p.size)]
        out += [f"noise[{r.name}]" for r in self.campaign.runs]
        out += [f"ar1[{r.name}]" for r, a in zip(self.campaign.runs, self.ar1) if a]
        return out

    def physics_values(self, u_phys) -> dict:
        """Constrained physics parameters from the first ``n_physics`` entries of u."""
        out, i = {}, 0
        for p in self.physics:
            v = tr.forward(p.constraint, u_phys[i:i + p.size])
            out[p.name] = v[0] if p.size == 1 else v
            i += p.size
        return out

    def physics_u(self, values: dict) -> np.ndarray:
        return np.concatenate([
            np.atleast_1d(np.asarray(tr.inverse(p.constraint, values[p.name]))) for p in self.physics
        ])

    def linear_values(self, beta) -> dict:
        out, i = {}, 0
        for p in self.linear:
            out[p.name] = beta[i:i + p.size]
            i += p.size
        return out

    def noise_values(self, u):
        """(σ_r innovation sd per run, ρ_r per run) from u; σ_r = √(s_r² + floor_r²)."""
        s = jnp.exp(u[self.n_physics:self.n_physics + self.n_runs])
        sigma = jnp.sqrt(s**2 + jnp.asarray(self.floors) ** 2)
        rho = jnp.zeros(self.n_runs)
        if self.n_ar1:
            logits = u[self.n_physics + self.n_runs:]
            rho = rho.at[np.flatnonzero(self.ar1)].set(jax.nn.sigmoid(logits))
        return sigma, rho

    # --- linear parts ----------------------------------------------------------------------
    def _design_matrices(self):
        """Per-run design matrix of the linear parameters (exact: they enter linearly)."""
        if not self.n_linear:
            return [jnp.zeros((len(y), 0)) for y in self.y]
        phys = self.physics_values(jnp.asarray(self.prior_mean))

        def lin_pred(beta):
            return self.model.predict({**phys, **self.linear_values(beta)}, self.inputs)

        zero = jnp.zeros(self.n_linear)
        base = lin_pred(zero)
        jac = jax.jacfwd(lin_pred)(zero)
        return [np.asarray(j) for j, _ in zip(jac, base)]

    def nonlinear_prediction(self, u_phys):
        """Predicted angle per run with every linear parameter at zero."""
        zero = self.linear_values(jnp.zeros(self.n_linear))
        return self.model.predict({**self.physics_values(u_phys), **zero}, self.inputs)

    # --- noise model -------------------------------------------------------------------------
    @staticmethod
    def whiten(x, sigma, rho):
        """AR(1) innovations of x, scaled by σ (Prais–Winsten for the first sample). Works on
        vectors and on the columns of a matrix."""
        first = x[:1] * jnp.sqrt(1.0 - rho**2)
        rest = x[1:] - rho * x[:-1]
        return jnp.concatenate([first, rest], axis=0) / sigma

    def profile(self, u):
        """Solve the linear parameters for u; return (whitened residuals per run, β, log det A)."""
        sigma, rho = self.noise_values(u)
        preds = self.nonlinear_prediction(u[:self.n_physics])
        e = [y - f for y, f in zip(self.y, preds)]
        if self.n_linear:
            wx = [self.whiten(jnp.asarray(x), sigma[r], rho[r]) for r, x in enumerate(self._design)]
            we = [self.whiten(e[r], sigma[r], rho[r]) for r in range(self.n_runs)]
            a = sum(w.T @ w for w in wx)
            b = sum(w.T @ v for w, v in zip(wx, we))
            a = a + 1e-10 * jnp.trace(a) / self.n_linear * jnp.eye(self.n_linear)
            beta = jnp.linalg.solve(a, b)
            white = [v - w @ beta for v, w in zip(we, wx)]
            logdet = jnp.linalg.slogdet(a)[1]
        else:
            beta = jnp.zeros(0)
            white = [self.whiten(e[r], sigma[r], rho[r]) for r in range(self.n_runs)]
            logdet = 0.0
        return white, beta, logdet

    def pointwise_log_likelihood(self, u):
        """Per-sample conditional log densities (list per run), linear parts at their optimum."""
        sigma, rho = self.noise_values(u)
        white, _, _ = self.profile(u)
        out = []
        for r, w in enumerate(white):
            if self.noise.student_t_dof:
                nu = self.noise.student_t_dof
                ll = (jax.scipy.special.gammaln((nu + 1) / 2) - jax.scipy.special.gammaln(nu / 2)
                      - 0.5 * jnp.log(nu * jnp.pi) - (nu + 1) / 2 * jnp.log1p(w**2 / nu))
            else:
                ll = -0.5 * w**2 - 0.5 * jnp.log(2 * jnp.pi)
            ll = ll - jnp.log(sigma[r])
            ll = ll.at[0].add(0.5 * jnp.log(1.0 - rho[r] ** 2))
            out.append(ll)
        return out

    def log_prior(self, u):
        """Normal in u (log-normal / normal on the natural scale, whose log-Jacobian this
        includes), for the physics and the noise parameters; ρ logit-normal(0, 1.5)."""
        z = (u[:self.n_physics] - self.prior_mean) / self.prior_sd
        lp = -0.5 * jnp.sum(z**2)
        zs = (u[self.n_physics:self.n_physics + self.n_runs] - self.noise_prior_mean) / self.noise_prior_sd
        lp = lp - 0.5 * jnp.sum(zs**2)
        if self.n_ar1:
            lp = lp - 0.5 * jnp.sum((u[self.n_physics + self.n_runs:] / 1.5) ** 2)
        return lp

    def log_density(self, u):
        """Log posterior of u (up to a constant), linear parameters marginalised (flat prior).
        Never NaN: a non-finite value becomes −inf."""
        pll = self.pointwise_log_likelihood(u)
        _, _, logdet = self.profile(u)
        lp = sum(jnp.sum(x) for x in pll) - 0.5 * logdet + self.log_prior(u)
        return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)

    def prior_residuals(self, u_phys):
        """Prior of the physics as pseudo-residuals for least squares."""
        return (u_phys - self.prior_mean) / self.prior_sd

    def full_values(self, u) -> dict:
        """Every model parameter (physics + linear at their optimum), SI."""
        _, beta, _ = self.profile(u)
        return {**self.physics_values(u[:self.n_physics]), **self.linear_values(beta)}
