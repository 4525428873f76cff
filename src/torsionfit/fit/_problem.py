"""A campaign turned into a fitting problem: parameter layout, priors, noise model, and the
log-density the optimiser and the sampler share.

``FitProblem`` is an equinox Module: arrays (data, design matrices, prior centres) are
leaves, the structure (model, parameter layout, AR(1) mask) is static. Functions of
(problem, u) are jitted once per *shape*: a second campaign with the same runs, lengths and
model reuses the compiled code.

Layout of the unconstrained vector u: the non-linear physics (one entry per element, in
``model.parameters()`` order), then log s_r per run (noise above the encoder floor), then
logit ρ_r for each run with AR(1) noise. The linear parameters (per-run offsets, drift,
kinematic harmonics) are not in u: for any u they are solved by weighted least squares
(variable projection) and, in the log-density, marginalised analytically under a flat
prior, so the sampler sees only the non-linear physics.
"""

from dataclasses import dataclass

import equinox as eqx
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
RHO_PRIOR_SD = 1.5  # logit-normal(0, 1.5) prior on each ρ_r
NOISE_PRIOR_SD = 3.0  # log-normal spread of the noise above the floor


@dataclass(frozen=True)
class NoiseOptions:
    """Likelihood options. ``ar1=None`` → AR(1) on for runs with ≥ 200 samples."""

    ar1: bool | None = None
    student_t_dof: float | None = None  # None: Gaussian; a number: Student-t with that many dof
    denoise_fraction: float = 0.125  # torque smoother half-width, fraction of each monotone segment


def model_inputs(campaign: Campaign, denoise_fraction: float = 0.125) -> list:
    """Per-run model inputs; hysteresis runs are driven by the denoised measured torque."""
    out = []
    for run in campaign.runs:
        if isinstance(run, HysteresisRun):
            out.append(m.hysteresis_input(run.time_s, denoise_torque(run.torque_Nm, denoise_fraction)))
        else:
            out.append(m.te_input(run.output_angle_rad, run.torque_Nm, run.speed_rpm, run.direction, run.time_s))
    return out


def observed(campaign: Campaign) -> list[np.ndarray]:
    return [np.asarray(r.angle_rad if isinstance(r, HysteresisRun) else r.te_rad, float) for r in campaign.runs]


def check_fittable(campaign: Campaign) -> None:
    """InputError (one line) for campaigns no fit can use."""
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


class FitProblem(eqx.Module):
    """Data, priors and structure of one fit; pure functions of u."""

    model: m.CampaignModel = eqx.field(static=True)
    physics: tuple = eqx.field(static=True)  # non-linear Parameters
    linear: tuple = eqx.field(static=True)  # linear Parameters (profiled)
    ar1: tuple = eqx.field(static=True)  # bool per run
    student_t_dof: float | None = eqx.field(static=True)
    inputs: list
    y: list
    design: list
    floors: jnp.ndarray
    prior_mean: jnp.ndarray
    prior_sd: jnp.ndarray
    noise_prior_mean: jnp.ndarray

    # --- sizes -----------------------------------------------------------------------------
    @property
    def n_runs(self) -> int:
        return len(self.ar1)

    @property
    def n_physics(self) -> int:
        return int(sum(p.size for p in self.physics))

    @property
    def n_linear(self) -> int:
        return int(sum(p.size for p in self.linear))

    @property
    def n_ar1(self) -> int:
        return int(sum(self.ar1))

    @property
    def dim(self) -> int:
        return self.n_physics + self.n_runs + self.n_ar1

    # --- parameter layout ------------------------------------------------------------------
    def names(self, run_names) -> list[str]:
        """Names of the entries of u (physics on their natural scale, noise as s_r, ρ_r)."""
        out = []
        for p in self.physics:
            out += [p.name] if p.size == 1 else [f"{p.name}[{i}]" for i in range(p.size)]
        out += [f"noise[{r}]" for r in run_names]
        out += [f"ar1[{r}]" for r, a in zip(run_names, self.ar1) if a]
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
        sigma = jnp.sqrt(s**2 + self.floors**2)
        rho = jnp.zeros(self.n_runs, dtype=s.dtype)
        if self.n_ar1:
            logits = u[self.n_physics + self.n_runs:]
            rho = rho.at[np.flatnonzero(self.ar1)].set(jax.nn.sigmoid(logits))
        return sigma, rho

    # --- predictions and residuals -----------------------------------------------------------
    def nonlinear_prediction(self, u_phys):
        """Predicted angle per run with every linear parameter at zero."""
        zero = self.linear_values(jnp.zeros(self.n_linear))
        return self.model.predict({**self.physics_values(u_phys), **zero}, self.inputs)

    @staticmethod
    def whiten(x, sigma, rho):
        """AR(1) innovations of x scaled by σ (Prais–Winsten first sample); vectors or columns."""
        first = x[:1] * jnp.sqrt(1.0 - rho**2)
        rest = x[1:] - rho * x[:-1]
        return jnp.concatenate([first, rest], axis=0) / sigma

    def profile(self, u):
        """Solve the linear parameters for u: (whitened residuals per run, β, log det A)."""
        sigma, rho = self.noise_values(u)
        preds = self.nonlinear_prediction(u[:self.n_physics])
        we = [self.whiten(y - f, sigma[r], rho[r]) for r, (y, f) in enumerate(zip(self.y, preds))]
        if not self.n_linear:
            return we, jnp.zeros(0), jnp.asarray(0.0)
        wx = [self.whiten(x, sigma[r], rho[r]) for r, x in enumerate(self.design)]
        a = sum(w.T @ w for w in wx)
        b = sum(w.T @ v for w, v in zip(wx, we))
        a = a + 1e-10 * jnp.trace(a) / self.n_linear * jnp.eye(self.n_linear)
        beta = jnp.linalg.solve(a, b)
        white = [v - w @ beta for v, w in zip(we, wx)]
        return white, beta, jnp.linalg.slogdet(a)[1]

    def _pointwise(self, white, sigma, rho):
        out = []
        for r, w in enumerate(white):
            if self.student_t_dof:
                nu = self.student_t_dof
                ll = (jax.scipy.special.gammaln((nu + 1) / 2) - jax.scipy.special.gammaln(nu / 2)
                      - 0.5 * jnp.log(nu * jnp.pi) - (nu + 1) / 2 * jnp.log1p(w**2 / nu))
            else:
                ll = -0.5 * w**2 - 0.5 * jnp.log(2 * jnp.pi)
            ll = ll - jnp.log(sigma[r])
            out.append(ll.at[0].add(0.5 * jnp.log(1.0 - rho[r] ** 2)))
        return out

    def pointwise_log_likelihood(self, u):
        """Per-sample conditional log densities (list per run), linear parts at their optimum."""
        sigma, rho = self.noise_values(u)
        white, _, _ = self.profile(u)
        return self._pointwise(white, sigma, rho)

    def log_prior(self, u):
        """Normal in u — log-normal / normal on the natural scale, whose log-Jacobian that
        includes — for physics and noise levels; ρ logit-normal(0, 1.5)."""
        z = (u[:self.n_physics] - self.prior_mean) / self.prior_sd
        lp = -0.5 * jnp.sum(z**2)
        zs = (u[self.n_physics:self.n_physics + self.n_runs] - self.noise_prior_mean) / NOISE_PRIOR_SD
        lp = lp - 0.5 * jnp.sum(zs**2)
        if self.n_ar1:
            lp = lp - 0.5 * jnp.sum((u[self.n_physics + self.n_runs:] / RHO_PRIOR_SD) ** 2)
        return lp

    def log_density(self, u):
        """Log posterior of u (up to a constant), linear parameters marginalised (flat prior).
        Never NaN: a non-finite value becomes −inf."""
        sigma, rho = self.noise_values(u)
        white, _, logdet = self.profile(u)
        ll = sum(jnp.sum(x) for x in self._pointwise(white, sigma, rho))
        lp = ll - 0.5 * logdet + self.log_prior(u)
        return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)

    def prior_residuals(self, u_phys):
        """Prior of the physics as pseudo-residuals for least squares."""
        return (u_phys - self.prior_mean) / self.prior_sd

    def full_values(self, u) -> dict:
        """Every model parameter (physics + linear at their optimum), SI."""
        _, beta, _ = self.profile(u)
        return {**self.physics_values(u[:self.n_physics]), **self.linear_values(beta)}

    def residuals(self, u) -> list:
        """Raw residuals y − prediction per run (rad), linear parts at their optimum."""
        preds = self.model.predict(self.full_values(u), self.inputs)
        return [y - f for y, f in zip(self.y, preds)]


def _design_matrices(model, inputs, physics, linear, prior_mean, y):
    """Per-run design matrix of the linear parameters (exact: they enter linearly)."""
    n_lin = int(sum(p.size for p in linear))
    if not n_lin:
        return [jnp.zeros((len(v), 0)) for v in y]
    shell = FitProblem(model, physics, linear, tuple(False for _ in y), None, inputs, y,
                       [jnp.zeros((len(v), 0)) for v in y], jnp.zeros(len(y)), prior_mean,
                       jnp.ones_like(prior_mean), jnp.zeros(len(y)))
    phys = shell.physics_values(prior_mean)

    def lin_pred(beta):
        return model.predict({**phys, **shell.linear_values(beta)}, inputs)

    return [jnp.asarray(j) for j in jax.jacfwd(lin_pred)(jnp.zeros(n_lin))]


def build_problem(campaign: Campaign, model: m.CampaignModel, noise: NoiseOptions = NoiseOptions()) -> FitProblem:
    """The fitting problem for ``campaign`` under ``model``; InputError on unusable data."""
    kinds = tuple(r.kind for r in campaign.runs)
    if model.run_kinds != kinds:
        raise ValueError(f"model is for runs {model.run_kinds}, campaign has {kinds}")
    check_fittable(campaign)
    params = model.parameters()
    physics = tuple(p for p in params if not p.linear)
    linear = tuple(p for p in params if p.linear)
    priors = build_priors(params, campaign)
    prior_mean = jnp.asarray(np.concatenate([np.full(p.size, priors[p.name][0]) for p in physics]))
    prior_sd = jnp.asarray(np.concatenate([np.full(p.size, priors[p.name][1]) for p in physics]))
    inputs = model_inputs(campaign, noise.denoise_fraction)
    y = [jnp.asarray(v) for v in observed(campaign)]
    floor = campaign.instrument.angle_floor_rad or 0.0
    ar1 = tuple(bool(len(r) >= AR1_MIN_SAMPLES) if noise.ar1 is None else bool(noise.ar1) for r in campaign.runs)
    # noise above the floor: log-normal around 1 % of the run's angle range (wide)
    ranges = np.array([max(float(np.ptp(np.asarray(v))), 1e-9) for v in y])
    design = _design_matrices(model, inputs, physics, linear, prior_mean, y)
    return FitProblem(
        model=model, physics=physics, linear=linear, ar1=ar1, student_t_dof=noise.student_t_dof,
        inputs=inputs, y=y, design=design, floors=jnp.full(len(y), floor),
        prior_mean=prior_mean, prior_sd=prior_sd, noise_prior_mean=jnp.asarray(np.log(1e-2 * ranges)),
    )
