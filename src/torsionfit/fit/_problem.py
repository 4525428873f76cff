"""A campaign turned into a fitting problem: parameter layout, priors, noise model, and the
log-density the optimiser and the sampler share.

``FitProblem`` is an equinox Module: arrays (data, design matrices, prior centres) are
leaves, the structure (model, parameter layout, AR(1) mask) is static. Functions of
(problem, u) are jitted once per *shape*: a second campaign with the same runs, lengths and
model reuses the compiled code.

Layout of the unconstrained vector u — the *non-linear block*: the physics (one entry per
element, in ``model.parameters()`` order), then the latent torque lines of each hysteresis
run (a level and a tilt per ramp); then log s_r per run (noise above the encoder floor), then logit(ρ_r/ρ_max) for each run
with AR(1) noise (ρ_max = :data:`RHO_MAX`).

The true drive torque is latent: the model is driven by the denoised measured torque plus, on
each ramp, a correction line (its level and its tilt across the ramp), each with a normal prior
whose sd is that of the smoother's error line (fit/_torque_error.py: ``ramp_line_basis``). A
ramp's smoothed torque is never exact, and its error is one line along the whole ramp, not an
error per sample: where the loop is steep (lost motion closing near zero torque, the friction
transition after a reversal) that ramp-long error, counted sample by sample, would be read as
physics with false confidence. The linear parameters (per-run offsets, drift,
kinematic harmonics) are not in u: for any u they are solved by weighted least squares
(variable projection) and, in the log-density, marginalised analytically under a flat
prior, so the sampler sees only the non-linear physics.
"""

import dataclasses
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._x64 import in_float64
from .. import model as m
from .._errors import InputError
from ..io import Campaign, HysteresisRun
from . import _transform as tr
from .._segments import fit_ramps
from ..metrics._hysteresis import small_cycle_rows
from ._denoise import denoise_torque
from ._noise_classes import conditioning_keep, ramp_amplitudes
from ._prior import build_priors
from ._torque_error import angle_variance_from_torque_error, ramp_line_basis, torque_line_labels

AR1_MIN_SAMPLES = 100  # the AR(1) default is on for runs at least this dense
RHO_PRIOR_SD = 1.5  # logit-normal(0, 1.5) prior on each ρ_r / ρ_max
#: the AR(1) coefficient's bound, ρ = ρ_max · sigmoid(u). AR(1) noise whose coefficient reaches 1
#: is a random walk, blind to the loop's level: where the model misses structure, a free ρ went
#: there and took the posterior off the data — on the measured baseline pos6 loop the mode of
#: the density with ρ free had ρ = 0.99983 and the loop 3617″ RMSE off the data, with ρ bounded
#: 1089″, the MAP's 923″ (the MAP held ρ at this bound already)
RHO_MAX = 0.995
NOISE_PRIOR_SD = 3.0  # log-normal spread of the noise above the floor
#: IRLS rounds of the linear parameters under a Student-t likelihood, from the Gaussian solution
#: (offsets and harmonics: a handful of columns, each round one small solve)
ROBUST_LINEAR_ITERATIONS = 8
#: EM rounds of the noise scale (and ρ) under a Student-t likelihood in each noise update
ROBUST_NOISE_ITERATIONS = 30


def student_t_weights(r2, nu: float):
    """The Student-t's scale-mixture (EM / IRLS) weights (ν+1)/(ν+r²) of squared standardised
    residuals ``r2``: ≈ 1 for a residual at the scale, → 0 for a jump far beyond it."""
    return (nu + 1.0) / (nu + r2)


@dataclass(frozen=True)
class NoiseOptions:
    """Likelihood options. ``ar1=None`` → AR(1) on for runs with ≥ 100 samples."""

    ar1: bool | None = None
    # None: Gaussian; a number: Student-t with that many dof — heavy tails for residuals that
    # move in jumps (a measured loop's stick-slip staircase, its gap crossed in a few samples).
    # The MAP is the Student-t one (fit_map minimises its negative log density, the noise scale by
    # its EM fixed point); the linear parameters are solved by iteratively reweighted least
    # squares and marginalised with the Gaussian formula at those weights.
    student_t_dof: float | None = None
    denoise_fraction: float | None = None  # smoother half-width per segment (None: by GCV)
    # True: the noise above the floor of a hysteresis run scales with the amplitude of the
    # torque cycle a sample belongs to (s_r is the level of the run's largest cycles). For
    # measured loops whose misfit grows with the load: with one level for a whole file the
    # ±4 N·m play ramps sit far below the ±40 N·m ramps' misfit and the fit ignores them.
    cycle_amplitude_noise: bool = False
    # True: a noise level per class of cycle amplitude (the play ramps, the stiffness ramps),
    # their ratios read from the residuals at the MAP and the fit repeated with them
    # (fit/_noise_classes.py); the run's noise parameter is the level of its largest cycles.
    cycle_class_noise: bool = False
    # True (with cycle_class_noise): the ramps that first load a run beyond its earlier peaks
    # (the first large ramp after the play ramps) are a class of their own among the largest
    # cycles, whose level (class 0) is then the repeated ramps' (fit/_noise_classes.py)
    first_excursion_class: bool = False
    # True: the first excursions of the largest cycles (the same ramps as first_excursion_class)
    # drive the model's state but are out of the likelihood — conditioning cycles, as a test
    # procedure runs before it records (FitProblem.likelihood_keep); kept when the run has no
    # repeats of its largest cycles to fit instead
    first_excursion_conditioning: bool = False
    # True: the denoised drive torque's error enters each hysteresis sample's variance as the
    # angle the *measured* loop branch moves across ±sd τ̂ (errors in variables, from the data:
    # fit/_torque_error.py). False: the angle noise alone (the latent torque lines stay).
    torque_error_variance: bool = True


CYCLE_NOISE_MIN_SHARE = 0.05  # smallest noise shape (share of the largest cycles' level)


def cycle_amplitude_shape(torque_Nm) -> np.ndarray:
    """Per-sample noise shape in (0, 1] of a hysteresis record: the peak |torque| of the monotone
    ramp a sample lies on over the record's largest, floored at ``CYCLE_NOISE_MIN_SHARE``."""
    amp = ramp_amplitudes(torque_Nm)
    top = float(np.max(amp)) if amp.size else 0.0
    if not top > 0:
        return np.ones(amp.size)
    return np.maximum(amp / top, CYCLE_NOISE_MIN_SHARE)


@in_float64
def model_inputs(campaign: Campaign, denoise_fraction: float | None = None, return_lines: bool = False):
    """Per-run model inputs; hysteresis runs are driven by the denoised measured torque. With
    ``return_lines`` also the variance of that torque per sample (zeros for TE runs) and each
    hysteresis run's :class:`RampLines` (None for TE)."""
    out, variances, lines = [], [], []
    for run in campaign.runs:
        if isinstance(run, HysteresisRun):
            tau, var, ramp_lines = denoise_torque(run.torque_Nm, denoise_fraction, return_lines=True)
            small = small_cycle_rows(run.time_s, run.torque_Nm, run.angle_rad, name=run.name)
            out.append(m.hysteresis_input(run.time_s, tau, campaign.temperature_delta_K(run), small))
            variances.append(var)
            lines.append(ramp_lines)
        else:
            out.append(m.te_input(run.output_angle_rad, run.torque_Nm, run.speed_rpm, run.direction, run.time_s,
                                  zero_group=campaign.te_zero_index(run),
                                  temperature_delta_K=campaign.temperature_delta_K(run)))
            variances.append(np.zeros(len(run)))
            lines.append(None)
    return (out, variances, lines) if return_lines else out


def observed(campaign: Campaign) -> list[np.ndarray]:
    return [np.asarray(r.angle_rad if isinstance(r, HysteresisRun) else r.te_rad, float) for r in campaign.runs]


def temperatures_resolving_friction(campaign: Campaign) -> list[float]:
    """The run temperatures (°C) at which compliance and friction level show apart: a
    hysteresis loop there (its width is friction, its slope the spring), or TE runs at two or
    more loads (friction is a larger share of a smaller load's twist)."""
    loads: dict[float, set] = {}
    out = set()
    for run in campaign.runs:
        t = campaign.run_temperature_C(run)
        if t is None:
            continue
        if isinstance(run, HysteresisRun):
            out.add(t)
        else:
            loads.setdefault(t, set()).add(round(abs(float(run.torque_Nm)), 9))
    return sorted(out | {t for t, s in loads.items() if len(s) >= 2})


def check_temperatures(campaign: Campaign, friction: bool = True) -> None:
    """InputError (one line) when a temperature-dependent model cannot be fitted: a run
    without a temperature, all runs at one temperature, or — with the friction level's
    temperature coefficient — fewer than two temperatures where the data tell compliance from
    friction (elsewhere both change a TE run's twist alike, and the fit would pick one of two
    mirror solutions with a confident, wrong interval)."""
    for run in campaign.runs:
        if campaign.run_temperature_C(run) is None:
            raise InputError(f"run {run.name!r}: temperature_dependence needs every run's temperature "
                             "(the run key temperature_C or a temperature column)")
    temps = sorted({campaign.run_temperature_C(r) for r in campaign.runs})
    if len(temps) < 2:
        raise InputError(f"temperature_dependence needs runs at two or more temperatures; all runs are at {temps[0]:g} °C")
    resolving = temperatures_resolving_friction(campaign)
    if friction and len(resolving) < 2:
        at = ", ".join(f"{t:g}" for t in resolving) or "none"
        raise InputError(
            "temperature_dependence: compliance and friction level show apart at fewer than two temperatures "
            f"(a loop, or TE at two or more loads, at: {at} °C); declare temperature_dependence = "
            "{friction = false} (compliance only) or measure loops or several loads at two temperatures")


def check_fittable(campaign: Campaign) -> None:
    """InputError (one line) for campaigns no fit can use."""
    if campaign.reducer.rated_torque_Nm is None:
        raise InputError(
            "[reducer].rated_torque_Nm is missing: model fits, acceptance and the paper need the "
            "rated torque as their torque scale (only `torsionfit metrics` works without it)"
        )
    if not campaign.runs:
        raise InputError("campaign has no runs to fit")
    for r in campaign.runs:
        arrays = {"time_s": r.time_s, "torque_Nm": r.torque_Nm, "angle_rad": r.angle_rad} if isinstance(r, HysteresisRun) \
            else {"output_angle_rad": r.output_angle_rad, "te_rad": r.te_rad}
        lengths = {k: len(np.asarray(v)) for k, v in arrays.items()}
        if len(set(lengths.values())) > 1:
            raise InputError(f"run {r.name!r}: arrays of unequal length {lengths}; expected one length")
        for k, v in arrays.items():
            bad = np.flatnonzero(~np.isfinite(np.asarray(v, float)))
            if bad.size:
                raise InputError(f"run {r.name!r}: {k} has {bad.size} non-finite (NaN/inf) value(s), first at sample {bad[0]}")
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
    # per sample, the angle variance the denoised drive torque's error puts into the measured
    # angle, rad² (errors in variables, read from the data; 0 for TE runs): constant in u
    eiv_var: list
    design: list
    torque_line_basis: list  # per run: (N, 2·ramps) level and tilt columns of the latent torque correction
    floors: jnp.ndarray
    prior_mean: jnp.ndarray
    prior_sd: jnp.ndarray
    noise_prior_mean: jnp.ndarray
    noise_shape: list | None = None  # per run: per-sample multiplier of s_r (None: constant)
    # the likelihood's power in log_density (1: Bayes; 1/k < 1: widened for structure the model
    # lacks, see fit/_misfit.py); the pointwise log-likelihood (LOO) is never tempered
    likelihood_power: float = np.float64(1.0)  # a NumPy scalar: traced, one compile for every power
    # the cycle classes split the first excursions off (NoiseOptions.first_excursion_class)
    first_excursion_class: bool = eqx.field(static=True, default=False)
    # per run: True where a sample is in the likelihood (None: every sample). The others still
    # drive the model's state (friction, gap) but weigh nothing: their whitened residual is 0,
    # their log density 0, and AR(1) whitening restarts after them
    likelihood_keep: list | None = None

    # --- sizes -----------------------------------------------------------------------------
    @property
    def n_runs(self) -> int:
        return len(self.ar1)

    @property
    def n_model(self) -> int:
        """Entries of u that are model parameters."""
        return int(sum(p.size for p in self.physics))

    @property
    def n_torque_lines(self) -> int:
        return int(sum(b.shape[1] for b in self.torque_line_basis))

    @property
    def n_nonlinear(self) -> int:
        """The non-linear block: model parameters and latent torque lines."""
        return self.n_model + self.n_torque_lines

    @property
    def n_linear(self) -> int:
        return int(sum(p.size for p in self.linear))

    @property
    def n_ar1(self) -> int:
        return int(sum(self.ar1))

    @property
    def dim(self) -> int:
        return self.n_nonlinear + self.n_runs + self.n_ar1

    # --- parameter layout ------------------------------------------------------------------
    def names(self, run_names) -> list[str]:
        """Names of the entries of u (model parameters, latent torque lines, then log s_r per
        run and logit(ρ_r/ρ_max) per AR(1) run; all in the unconstrained space)."""
        out = []
        for p in self.physics:
            out += [p.name] if p.size == 1 else [f"{p.name}[{i}]" for i in range(p.size)]
        for r, b in zip(run_names, self.torque_line_basis):
            out += [f"torque_line[{r}]{label}" for label in torque_line_labels(b.shape[1])]
        out += [f"noise[{r}]" for r in run_names]
        out += [f"ar1[{r}]" for r, a in zip(run_names, self.ar1) if a]
        return out

    def vanishing_at_zero(self) -> set[int]:
        """Indices in u of the model parameters whose zero limit is the model without their
        effect (:attr:`~torsionfit.model.Parameter.vanishes_at_zero`)."""
        out, i = set(), 0
        for p in self.physics:
            if p.vanishes_at_zero:
                out |= set(range(i, i + p.size))
            i += p.size
        return out

    def physics_values(self, u_phys) -> dict:
        """Constrained model parameters from the first ``n_model`` entries of u."""
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
        s = jnp.exp(u[self.n_nonlinear:self.n_nonlinear + self.n_runs])
        sigma = jnp.sqrt(s**2 + self.floors**2)
        rho = jnp.zeros(self.n_runs, dtype=s.dtype)
        if self.n_ar1:
            logits = u[self.n_nonlinear + self.n_runs:]
            rho = rho.at[np.flatnonzero(self.ar1)].set(RHO_MAX * jax.nn.sigmoid(logits))
        return sigma, rho

    # --- predictions and residuals -----------------------------------------------------------
    def corrected_inputs(self, u_nl):
        """Model inputs with the latent torque correction of u applied."""
        out, i = [], self.n_model
        for inp, basis in zip(self.inputs, self.torque_line_basis):
            k = basis.shape[1]
            if k:
                inp = eqx.tree_at(lambda x: x.torque_Nm, inp, inp.torque_Nm + basis @ u_nl[i:i + k])
            out.append(inp)
            i += k
        return out

    def nonlinear_prediction(self, u_nl):
        """Predicted angle per run with every linear parameter at zero."""
        zero = self.linear_values(jnp.zeros(self.n_linear))
        return self.model.predict({**self.physics_values(u_nl), **zero}, self.corrected_inputs(u_nl))

    # --- the samples of every run as one vector ---------------------------------------------
    # For work over all runs at once (the closed-form noise update sums each run's residual
    # pairs by segment: one program of a fixed size, where a loop over the runs grew with them).
    @property
    def run_lengths(self) -> tuple[int, ...]:
        """Samples per run (static: the arrays' shapes)."""
        return tuple(int(np.shape(v)[0]) for v in self.y)

    def split_runs(self, x) -> list:
        """A per-sample array of all runs (campaign order, along axis 0) → one array per run."""
        return jnp.split(x, np.cumsum(self.run_lengths)[:-1])

    def per_sample(self, per_run):
        """(R,) per-run values → (N,) per-sample values."""
        return jnp.concatenate([jnp.broadcast_to(per_run[r], (n,)) for r, n in enumerate(self.run_lengths)])

    def sum_runs(self, x):
        """(N,) per-sample values of all runs → (R,) their sum over each run."""
        ids = self.per_sample(jnp.arange(self.n_runs))
        return jax.ops.segment_sum(x, ids, num_segments=self.n_runs, indices_are_sorted=True)

    def first_samples(self):
        """(N,) True at the first sample of each run (where AR(1) whitening restarts)."""
        return jnp.concatenate([jnp.arange(n) == 0 for n in self.run_lengths])

    @staticmethod
    def whiten(x, scale, rho):
        """AR(1) innovations of x divided by the per-sample scale (Prais–Winsten first
        sample); x a vector or a matrix of columns, scale a scalar or a vector."""
        first = x[:1] * jnp.sqrt(1.0 - rho**2)
        rest = x[1:] - rho * x[:-1]
        innov = jnp.concatenate([first, rest], axis=0)
        return innov / (scale[:, None] if jnp.ndim(scale) and innov.ndim == 2 else scale)

    @staticmethod
    def restarts(keep):
        """(N,) True where AR(1) whitening restarts: the first sample of each kept stretch."""
        return keep & jnp.concatenate([jnp.ones(1, bool), ~keep[:-1]])

    @classmethod
    def whiten_kept(cls, x, scale, rho, keep):
        """:meth:`whiten` with the samples where ``keep`` is False out: 0 there, and the first
        kept sample after them whitened as a run's first (their residuals do not enter)."""
        col = (lambda v: v[:, None]) if x.ndim == 2 else (lambda v: v)  # noqa: E731
        prev = jnp.concatenate([jnp.zeros_like(x[:1]), x[:-1]], axis=0)
        innov = jnp.where(col(cls.restarts(keep)), x * jnp.sqrt(1.0 - rho**2), x - rho * prev)
        innov = innov / (scale[:, None] if jnp.ndim(scale) and innov.ndim == 2 else scale)
        return jnp.where(col(keep), innov, 0.0)

    def whiten_run(self, r: int, x, scale, rho):
        """Run r's residuals or design whitened, the samples out of the likelihood at 0."""
        if self.likelihood_keep is None:
            return self.whiten(x, scale, rho)
        return self.whiten_kept(x, scale, rho, self.likelihood_keep[r])

    def kept_samples(self) -> list[np.ndarray]:
        """Per run: True where a sample is in the likelihood (NumPy)."""
        if self.likelihood_keep is None:
            return [np.ones(n, dtype=bool) for n in self.run_lengths]
        return [np.asarray(k, dtype=bool) for k in self.likelihood_keep]

    # The likelihood is evaluated run by run: written over all runs' samples at once (each run's
    # σ_r, ρ_r spread over its samples) its program compiled faster for many runs, but the
    # log-density of one 10 001-sample loop under emcee's walkers ran a quarter slower (3.0 → 3.8
    # ms per 16 walkers). The ``*_all`` views concatenate the runs for callers that want them.
    def sample_scales(self, u) -> list:
        """Innovation sd per sample: √(σ_r² + eiv_i), eiv_i the angle variance the denoised drive
        torque's error causes where the measured loop is steep (e.g. while lost motion closes
        around zero torque); read from the data, so no parameter can widen it."""
        return [jnp.sqrt(sg**2 + v) for sg, v in zip(self.sample_sigma(u), self.eiv_var)]

    def sample_sigma(self, u) -> list:
        """Noise sd per run (a scalar) or per sample (with a noise shape): √((s_r w_i)² + floor_r²)."""
        if self.noise_shape is None:
            return list(self.noise_values(u)[0])
        s = jnp.exp(u[self.n_nonlinear:self.n_nonlinear + self.n_runs])
        return [jnp.sqrt((s[r] * w) ** 2 + self.floors[r] ** 2) for r, w in enumerate(self.noise_shape)]

    def whitened_design(self, scales, rho) -> jnp.ndarray:
        """The linear parameters' design of every run, whitened as the residuals, (N, n_linear);
        ``scales`` (N,) per sample, ``rho`` per run."""
        scales = self.split_runs(scales)
        return jnp.concatenate([self.whiten_run(r, x, scales[r], rho[r]) for r, x in enumerate(self.design)], axis=0)

    def profile(self, u, return_scales: bool = False):
        """Solve the linear parameters for u: (whitened residuals per run, β, log det A[, scales
        per run])."""
        _, rho = self.noise_values(u)
        preds = self.nonlinear_prediction(u[:self.n_nonlinear])
        scales = self.sample_scales(u)
        we = [self.whiten_run(r, y - f, scales[r], rho[r]) for r, (y, f) in enumerate(zip(self.y, preds))]
        if not self.n_linear:
            out = (we, jnp.zeros(0), jnp.asarray(0.0))
            return out + (scales,) if return_scales else out
        wx = [self.whiten_run(r, x, scales[r], rho[r]) for r, x in enumerate(self.design)]
        a = sum(w.T @ w for w in wx)
        b = sum(w.T @ v for w, v in zip(wx, we))
        a = a + 1e-10 * jnp.trace(a) / self.n_linear * jnp.eye(self.n_linear)
        beta = jnp.linalg.solve(a, b)
        if self.student_t_dof:
            beta, a = self._reweighted_linear(jnp.concatenate(wx), jnp.concatenate(we), beta)
        white = [v - w @ beta for v, w in zip(we, wx)]
        out = (white, beta, jnp.linalg.slogdet(a)[1])
        return out + (scales,) if return_scales else out

    def _reweighted_linear(self, wx, we, beta):
        """(β, A) of the linear parameters under the Student-t likelihood: iteratively reweighted
        least squares from the Gaussian ``beta`` (weights (ν+1)/(ν+r²) of the whitened residual r,
        the EM weights of the t's scale mixture), and A = XᵀWX at the last weights."""
        nu = self.student_t_dof
        for _ in range(ROBUST_LINEAR_ITERATIONS):
            weight = student_t_weights((we - wx @ beta) ** 2, nu)
            a = wx.T @ (weight[:, None] * wx)
            a = a + 1e-10 * jnp.trace(a) / self.n_linear * jnp.eye(self.n_linear)  # the Gaussian solve's ridge
            beta = jnp.linalg.solve(a, wx.T @ (weight * we))
        return beta, a

    def objective_residuals(self, white):
        """The whitened residuals as least squares sees them: themselves under the Gaussian
        likelihood; under the Student-t, pseudo-residuals ρ = w·√((ν+1)/ν · log1p(x)/x),
        x = w²/ν, whose ½Σρ² = Σ (ν+1)/2 · log(1 + w²/ν) is its negative log density up to a
        constant (smooth through w = 0, where ρ ≈ w·√((ν+1)/ν))."""
        if not self.student_t_dof:
            return white
        nu = self.student_t_dof
        x = white**2 / nu
        small = x < 1e-8
        ratio = jnp.where(small, 1.0 - 0.5 * x, jnp.log1p(x) / jnp.where(small, 1.0, x))
        return white * jnp.sqrt((nu + 1.0) / nu * ratio)

    def profile_all(self, u):
        """:meth:`profile` with all runs concatenated: (whitened residuals (N,), β, log det A,
        per-sample scales (N,), ρ per run)."""
        _, rho = self.noise_values(u)
        white, beta, logdet, scales = self.profile(u, return_scales=True)
        return jnp.concatenate(white), beta, logdet, jnp.concatenate(scales), rho

    def _pointwise(self, white, scales, rho):
        out = []
        for r, w in enumerate(white):
            if self.student_t_dof:
                nu = self.student_t_dof
                ll = (jax.scipy.special.gammaln((nu + 1) / 2) - jax.scipy.special.gammaln(nu / 2)
                      - 0.5 * jnp.log(nu * jnp.pi) - (nu + 1) / 2 * jnp.log1p(w**2 / nu))
            else:
                ll = -0.5 * w**2 - 0.5 * jnp.log(2 * jnp.pi)
            ll = ll - jnp.log(scales[r])
            if self.likelihood_keep is None:
                out.append(ll.at[0].add(0.5 * jnp.log(1.0 - rho[r] ** 2)))
                continue
            keep = self.likelihood_keep[r]
            ll = ll + jnp.where(self.restarts(keep), 0.5 * jnp.log(1.0 - rho[r] ** 2), 0.0)
            out.append(jnp.where(keep, ll, 0.0))
        return out

    def pointwise_log_likelihood(self, u):
        """Per-sample conditional log densities (list per run), linear parts at their optimum."""
        _, rho = self.noise_values(u)
        white, _, _, scales = self.profile(u, return_scales=True)
        return self._pointwise(white, scales, rho)

    def log_prior(self, u):
        """Normal in u — log-normal / normal on the natural scale, whose log-Jacobian that
        includes — for physics and noise levels; ρ/ρ_max logit-normal(0, 1.5)."""
        z = (u[:self.n_nonlinear] - self.prior_mean) / self.prior_sd
        lp = -0.5 * jnp.sum(z**2)
        zs = (u[self.n_nonlinear:self.n_nonlinear + self.n_runs] - self.noise_prior_mean) / NOISE_PRIOR_SD
        lp = lp - 0.5 * jnp.sum(zs**2)
        if self.n_ar1:
            lp = lp - 0.5 * jnp.sum((u[self.n_nonlinear + self.n_runs:] / RHO_PRIOR_SD) ** 2)
        return lp

    def log_density(self, u):
        """Log posterior of u (up to a constant), linear parameters marginalised (flat prior).
        Never NaN: a non-finite value becomes −inf."""
        _, rho = self.noise_values(u)
        white, _, logdet, scales = self.profile(u, return_scales=True)
        ll = sum(jnp.sum(x) for x in self._pointwise(white, scales, rho))
        # the linear block's Gaussian integral under a power η changes −½ log det A by a constant
        lp = self.likelihood_power * ll - 0.5 * logdet + self.log_prior(u)
        return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)

    def prior_residuals(self, u_phys):
        """Prior of the physics as pseudo-residuals for least squares."""
        return (u_phys - self.prior_mean) / self.prior_sd

    def full_values(self, u) -> dict:
        """Every model parameter (physics + linear at their optimum), SI."""
        _, beta, _ = self.profile(u)
        return {**self.physics_values(u[:self.n_nonlinear]), **self.linear_values(beta)}

    def residuals(self, u) -> list:
        """Raw residuals y − prediction per run (rad), linear parts at their optimum."""
        preds = self.model.predict(self.full_values(u), self.corrected_inputs(u))
        return [y - f for y, f in zip(self.y, preds)]


def _design_matrices(model, inputs, physics, linear, prior_mean, y):
    """Per-run design matrix of the linear parameters (exact: they enter linearly)."""
    n_lin = int(sum(p.size for p in linear))
    if not n_lin:
        return [jnp.asarray(np.zeros((len(v), 0))) for v in y]
    # NumPy placeholders: every eager jnp call compiles a small program of its own
    shell = FitProblem(model, physics, linear, tuple(False for _ in y), None, inputs, y,
                       [np.zeros(len(v)) for v in y], [np.zeros((len(v), 0)) for v in y],
                       [np.zeros((len(v), 0)) for v in y], np.zeros(len(y)), prior_mean,
                       np.ones_like(prior_mean), np.zeros(len(y)))
    return [jnp.asarray(j) for j in _linear_jacobian(shell, prior_mean, n_lin)]


@eqx.filter_jit
def _linear_jacobian(shell, u_phys, n_lin: int):
    """d prediction / d linear parameters per run at the physics ``u_phys`` (jitted: eagerly,
    every scan of the model compiles anew on each call, a tenth of a second per campaign)."""
    phys = shell.physics_values(u_phys)

    def lin_pred(beta):
        return shell.model.predict({**phys, **shell.linear_values(beta)}, shell.inputs)

    return jax.jacfwd(lin_pred)(jnp.zeros(n_lin))


def _likelihood_keep(campaign: Campaign, inputs, first_excursions: bool) -> list | None:
    """Per run: True on the samples in the likelihood — not the manifest's conditioning rows
    (``[runs.condition]``), nor, with ``first_excursions``, the first excursions of the largest
    cycles; None when every sample is in."""
    if not first_excursions and all(getattr(r, "conditioning", None) is None for r in campaign.runs):
        return None
    keep = []
    for run, inp in zip(campaign.runs, inputs):
        k = np.ones(len(run), dtype=bool)
        if isinstance(run, HysteresisRun):
            if run.conditioning is not None:
                k &= ~np.asarray(run.conditioning, dtype=bool)
            if first_excursions:
                k &= conditioning_keep(np.asarray(inp.torque_Nm))
        if not k.any():
            raise InputError(f"run {run.name!r}: every sample is conditioning; nothing is left to fit")
        keep.append(jnp.asarray(k))
    return keep


@in_float64
def build_problem(campaign: Campaign, model: m.CampaignModel, noise: NoiseOptions = NoiseOptions(),
                  latent_torque: bool = True, gap_prior_from_crossings: bool = False) -> FitProblem:
    """The fitting problem for ``campaign`` under ``model``; InputError on unusable data.
    ``gap_prior_from_crossings``: :func:`~torsionfit.fit._prior.build_priors`' ``gap_from_crossings``."""
    kinds = tuple(r.kind for r in campaign.runs)
    if model.run_kinds != kinds:
        raise ValueError(f"model is for runs {model.run_kinds}, campaign has {kinds}")
    if campaign.te_runs and model.te_zero_groups != len(campaign.te_zero_groups):
        # one TE zero per zero group of the campaign (manifest key zero_group)
        model = dataclasses.replace(model, te_zero_groups=len(campaign.te_zero_groups))
    check_fittable(campaign)
    if model.temperature is not None:
        check_temperatures(campaign, model.temperature.friction)
    params = model.parameters()
    physics = tuple(p for p in params if not p.linear)
    linear = tuple(p for p in params if p.linear)
    priors = build_priors(params, campaign, gap_from_crossings=gap_prior_from_crossings)
    prior_mean = np.concatenate([np.full(p.size, priors[p.name][0]) for p in physics])
    prior_sd = np.concatenate([np.full(p.size, priors[p.name][1]) for p in physics])
    inputs, torque_var, ramp_lines = model_inputs(campaign, noise.denoise_fraction, return_lines=True)
    y = [jnp.asarray(v) for v in observed(campaign)]
    floor = campaign.instrument.angle_floor_rad or 0.0
    ar1 = tuple(bool(len(r) >= AR1_MIN_SAMPLES) if noise.ar1 is None else bool(noise.ar1) for r in campaign.runs)
    # noise above the floor: log-normal around 1 % of the run's angle range (wide)
    ranges = np.array([max(float(np.ptp(np.asarray(v))), 1e-9) for v in y])
    design = _design_matrices(model, inputs, physics, linear, prior_mean, y)
    bases, line_sd, eiv_var = [], [], []
    for run, inp, var, lines in zip(campaign.runs, inputs, torque_var, ramp_lines):
        hysteresis = isinstance(run, HysteresisRun)
        if hysteresis and latent_torque:
            # each ramp's line of error is latent (correlated along the ramp); the per-sample
            # variance keeps only what the lines leave
            basis, sd, var = ramp_line_basis(lines, var)
            bases.append(jnp.asarray(basis))
            line_sd.append(np.maximum(sd, 1e-6))
        else:
            bases.append(jnp.asarray(np.zeros((len(run), 0))))
        eiv_var.append(angle_variance_from_torque_error(run.angle_rad, run.torque_Nm, inp.torque_Nm, var)
                       if hysteresis and noise.torque_error_variance else np.zeros(len(run)))
    shape = None
    if noise.cycle_amplitude_noise and noise.cycle_class_noise:
        raise ValueError("NoiseOptions: cycle_amplitude_noise and cycle_class_noise are two shapes of the same "
                         "noise level; choose one")
    if noise.student_t_dof is not None and not (np.isfinite(noise.student_t_dof) and noise.student_t_dof > 0):
        raise ValueError(f"NoiseOptions: student_t_dof must be a positive number of degrees of freedom (or None "
                         f"for Gaussian noise), got {noise.student_t_dof!r}")
    if noise.first_excursion_class and not noise.cycle_class_noise:
        raise ValueError("NoiseOptions: first_excursion_class is a cycle class: it needs cycle_class_noise")
    if noise.first_excursion_conditioning and noise.first_excursion_class:
        raise ValueError("NoiseOptions: first_excursion_conditioning takes the first excursions out of the "
                         "likelihood; a noise class of their own (first_excursion_class) has nothing to weigh")
    keep = _likelihood_keep(campaign, inputs, noise.first_excursion_conditioning)
    if noise.cycle_class_noise:
        # one level for now: the fit sets the class shares at its MAP (fit/_noise_classes.py)
        shape = [jnp.ones(len(run)) for run in campaign.runs]
    if noise.cycle_amplitude_noise:
        shape = [jnp.asarray(cycle_amplitude_shape(run.torque_Nm) if isinstance(run, HysteresisRun)
                             else np.ones(len(run))) for run in campaign.runs]
    if line_sd:
        prior_mean = np.concatenate([prior_mean, np.zeros(sum(len(k) for k in line_sd))])
        prior_sd = np.concatenate([prior_sd, *line_sd])
    return FitProblem(
        model=model, physics=physics, linear=linear, ar1=ar1, student_t_dof=noise.student_t_dof,
        inputs=inputs, y=y, eiv_var=[jnp.asarray(v) for v in eiv_var],
        design=design, torque_line_basis=bases, floors=jnp.asarray(np.full(len(y), floor)),
        prior_mean=jnp.asarray(prior_mean), prior_sd=jnp.asarray(prior_sd), noise_prior_mean=jnp.asarray(np.log(1e-2 * ranges)),
        noise_shape=shape, first_excursion_class=noise.first_excursion_class, likelihood_keep=keep,
    )
