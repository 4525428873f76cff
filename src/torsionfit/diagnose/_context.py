"""What a residual signature looks at: per run, the residuals of a fitted model, the noise
model that whitens them, and the variables an effect may depend on."""

from dataclasses import dataclass, field, replace
from functools import cached_property

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy.stats import median_abs_deviation

from .._x64 import in_float64
from ..fit import FitProblem, MapResult
from ..io import Campaign


#: the largest AR(1) coefficient read off a variogram: a residual whose semivariance rises faster
#: from lag 1 to lag 2 than this allows is not AR(1) noise there, and ρ stops at the bound
RHO_BOUND = 0.95


@dataclass(frozen=True, eq=False)
class RunView:
    """One run as a signature sees it (SI units; arrays of the run's length)."""

    name: str
    kind: str  # "hysteresis" | "transmission_error"
    time_s: np.ndarray
    residual: np.ndarray  # measured − predicted, rad
    scale: np.ndarray  # innovation sd per sample, rad (measurement noise, see variogram_noise)
    rho: float  # AR(1) coefficient of the measurement noise
    drive_torque_Nm: np.ndarray  # the torque driving the model (denoised + latent correction)
    mesh_torque_Nm: np.ndarray
    measured_angle_rad: np.ndarray  # the measured angle (hysteresis) or output angle (TE)
    output_angle_rad: np.ndarray | None  # TE runs
    speed_rad_s: float  # TE runs: output speed; 0 for hysteresis
    direction: float  # TE runs: ±1; 0 for hysteresis
    loading_rate_Nm_per_s: float | None
    sensitivity: np.ndarray  # dθ̂/dτ̂ along the run (rad/N·m), for torque-offset signatures
    design: np.ndarray  # the fit's linear design (offsets, drift, harmonics): nuisance columns, one per
    # linear parameter in the same order in every run (a parameter shared by runs, like the TE zero, is one column)
    eiv_var: np.ndarray  # the fit's errors-in-variables variance per sample, rad²
    floor: float  # the encoder's quantisation floor, rad
    local_design: np.ndarray | None = None  # nuisance columns of this run alone (a signature's own additions)
    # for signatures robust to jumps (fit_context(robust=True)): the noise read from median
    # increments (robust_variogram_noise), as scale per sample and ρ, and the prediction's Jacobian
    # (N, p) with respect to the fit's physics, the winsorised test's nuisance
    robust_scale: np.ndarray | None = None
    robust_rho: float = 0.0
    physics_design: np.ndarray | None = None

    @property
    def robust(self) -> bool:
        return self.robust_scale is not None

    def renoised(self, residual: np.ndarray) -> "RunView":
        """This view with its measurement noise re-estimated (``variogram_noise``, and
        ``robust_variogram_noise`` for a robust view) from ``residual`` — e.g. the residual with a
        found periodic error removed, whose fast swings would otherwise pass for noise."""
        sd, rho = variogram_noise(residual)
        out = replace(self, scale=np.sqrt(self.eiv_var + max(sd, self.floor) ** 2), rho=rho)
        return out.with_robust_noise(residual) if self.robust else out

    def with_robust_noise(self, residual: np.ndarray) -> "RunView":
        """This view with the noise of ``residual`` read from median increments as well
        (``robust_variogram_noise``, floored by the encoder, the errors in variables kept)."""
        sd, rho = robust_variogram_noise(residual)
        return replace(self, robust_scale=np.sqrt(self.eiv_var + max(sd, self.floor) ** 2), robust_rho=rho)

    def white_at_bound(self) -> "RunView":
        """This view with each noise reading whose ρ sits at ``RHO_BOUND`` read as white from
        one-sample increments instead: ρ = 0 and the sd of γ(1) = σ²/(1 + ρ), floored by the
        encoder, the errors in variables kept. At the bound the short-lag variogram is not AR(1)
        noise, and whitening with ρ = 0.95 would difference away the smooth structure a test of
        what the model leaves looks for."""
        def white(scale, rho):
            sd = np.sqrt(np.maximum(scale**2 - self.eiv_var, 0.0) / (1.0 + rho))
            return np.sqrt(self.eiv_var + np.maximum(sd, self.floor) ** 2)

        out = self
        if self.rho >= RHO_BOUND:
            out = replace(out, scale=white(self.scale, self.rho), rho=0.0)
        if self.robust and self.robust_rho >= RHO_BOUND:
            out = replace(out, robust_scale=white(self.robust_scale, self.robust_rho), robust_rho=0.0)
        return out

    def whiten(self, x: np.ndarray, robust: bool = False) -> np.ndarray:
        """The AR(1) whitening with per-sample scales, on a vector or the columns of a matrix;
        ``robust``: with the noise read from median increments."""
        scale, rho = (self.robust_scale, self.robust_rho) if robust else (self.scale, self.rho)
        x = np.asarray(x, float)
        out = np.empty_like(x)
        out[:1] = x[:1] * np.sqrt(1.0 - rho**2)
        out[1:] = x[1:] - rho * x[:-1]
        return out / (scale[:, None] if x.ndim == 2 else scale)


@dataclass(frozen=True, eq=False)
class FitContext:
    """A campaign, the model fitted to it and the per-run views of its residuals."""

    campaign: Campaign
    effects: dict
    map_result: MapResult
    runs: tuple[RunView, ...]
    rated_torque_Nm: float

    @property
    def hysteresis(self) -> tuple[RunView, ...]:
        return tuple(r for r in self.runs if r.kind == "hysteresis")

    @property
    def te(self) -> tuple[RunView, ...]:
        return tuple(r for r in self.runs if r.kind == "transmission_error")

    #: physics_directions when fit_context computed them with the views (campaigns with
    #: hysteresis runs, whose friction and gap score tests read them)
    computed_directions: tuple | None = field(default=None, repr=False)

    @cached_property
    def physics_directions(self):
        """(prediction per run, its Jacobian per run with respect to every physics parameter of
        the fitted model) at the fit — what a refit of the present parameters would absorb. Every
        score test of one iteration projects it out; computed once per fit (its program is the
        largest a signature compiles), in float64 as the fit."""
        if self.computed_directions is not None:
            return self.computed_directions
        return _physics_directions(self.map_result.problem, jnp.asarray(self.map_result.u))


@eqx.filter_jit
def _views(problem: FitProblem, u):
    return _views_of(problem, u)


def _views_of(problem: FitProblem, u):
    values = problem.full_values(u)
    inputs = problem.corrected_inputs(u)
    comps = problem.model.components(values, inputs)
    preds = [c["total"] for c in comps]
    scales = problem.sample_scales(u)
    _, rho = problem.noise_values(u)
    return preds, [c["mesh_torque"] for c in comps], scales, rho, inputs


@eqx.filter_jit
def _views_and_directions(problem: FitProblem, u):
    """:func:`_views` and :func:`_physics_directions` in one program: one model evaluation and
    profile for both, where two programs compiled them twice for every fit diagnosed."""
    return _views_of(problem, u), _directions_of(problem, u)


@in_float64
@eqx.filter_jit
def _physics_directions(problem: FitProblem, u):
    return _directions_of(problem, u)


def _directions_of(problem: FitProblem, u):
    values = problem.full_values(u)
    inputs = problem.corrected_inputs(u[:problem.n_nonlinear])
    phys = {p.name: values[p.name] for p in problem.physics}
    pred = problem.model.predict(values, inputs)
    jac = jax.jacfwd(lambda ph: problem.model.predict({**values, **ph}, inputs))(phys)
    return pred, jac


def variogram_noise(residual: np.ndarray) -> tuple[float, float]:
    """(innovation sd, ρ) of AR(1) noise from the residual's short-lag variogram.

    γ(1) = σ_m²(1 − ρ), γ(2) = σ_m²(1 − ρ²), so ρ = γ(2)/γ(1) − 1. A smooth misfit (what a
    missing effect leaves) hardly changes increments over one or two samples, so unlike the
    fit's AR(1) estimate — which a misfit drives towards ρ → 1, whitening the very structure
    a signature looks for — this sees the measurement noise only.
    """
    e = np.asarray(residual, float)
    if e.size < 8:
        return float(np.std(e)) or 1e-12, 0.0
    return _ar1_noise(0.5 * np.mean(np.diff(e) ** 2), 0.5 * np.mean((e[2:] - e[:-2]) ** 2))


def _ar1_noise(g1: float, g2: float) -> tuple[float, float]:
    """(innovation sd, ρ) of AR(1) noise with semivariances γ(1) = ``g1`` and γ(2) = ``g2``."""
    if not g1 > 0:  # a constant residual, or below the encoder step: the caller's floor decides
        return 1e-12, 0.0
    rho = float(np.clip(g2 / g1 - 1.0, 0.0, RHO_BOUND))
    return float(np.sqrt(g1 / (1.0 - rho) * (1.0 - rho**2))) or 1e-12, rho


def robust_variogram_noise(residual: np.ndarray) -> tuple[float, float]:
    """(innovation sd, ρ) as :func:`variogram_noise`, with each lag's semivariance read from the
    median absolute increment instead of the mean square: a residual that moves in jumps
    (stick-slip steps, outliers, a gap crossed between samples) leaves most increments at the
    measurement noise, and the median reads them — the mean square counts every jump as noise."""
    e = np.asarray(residual, float)
    if e.size < 8:
        return float(median_abs_deviation(e, scale="normal")) or 1e-12, 0.0
    return _ar1_noise(0.5 * float(median_abs_deviation(np.diff(e), scale="normal")) ** 2,
                      0.5 * float(median_abs_deviation(e[2:] - e[:-2], scale="normal")) ** 2)


#: a run's residual "moves in jumps" when the robust sd of its increments (over √2) is below this
#: share of the variogram's innovation sd: 1 for white noise, 1/√(1 + ρ) ≈ 0.73 for AR(1) noise at
#: ρ = 0.9, about the same with a smooth misfit on top; 0.14 on a measured loop's block means
JUMP_RATIO = 0.5


def jump_reading(residual: np.ndarray, floor: float) -> tuple[float, float]:
    """(the sample-to-sample noise read from the median absolute increment, floored by the
    encoder's quantisation ``floor``; the mean-square variogram's innovation sd), both rad. Below
    the encoder step the median increment is 0 and the occasional step of the quantisation is no
    jump: hence the floor."""
    e = np.asarray(residual, float)
    if e.size < 8:
        return 0.0, 0.0
    robust = max(float(median_abs_deviation(np.diff(e), scale="normal")) / np.sqrt(2.0), float(floor))
    return robust, variogram_noise(e)[0]


def moves_in_jumps(robust: float, sd: float) -> bool:
    """Whether a residual whose :func:`jump_reading` is (``robust``, ``sd``) moves in jumps."""
    return sd > 0 and robust < JUMP_RATIO * sd


@in_float64
def fit_context(campaign: Campaign, effects: dict, map_result: MapResult, robust: bool = False) -> FitContext:
    """The views of ``map_result``'s residuals; ``robust``: when a run's residual moves in jumps
    (:func:`moves_in_jumps`), every view with its noise read from median increments as well
    (:func:`robust_variogram_noise`) and the fit's physics directions, for signatures robust to
    the jumps (see ``regression_evidence``). Without jumps the least-squares test is the
    efficient one, and the winsorised test reads a large misfit as jumps."""
    problem = map_result.problem
    u = jnp.asarray(map_result.u)
    directions = None
    if any(run.kind == "hysteresis" for run in campaign.runs):
        (preds, mesh, scales, rho, inputs), directions = _views_and_directions(problem, u)
    else:
        preds, mesh, scales, rho, inputs = _views(problem, u)
    sigma_fit, _ = problem.noise_values(u)
    views = []
    noise = []
    for i in range(len(campaign.runs)):
        sd, r = variogram_noise(np.asarray(problem.y[i]) - np.asarray(preds[i]))
        # keep the fit's per-sample errors-in-variables part, swap its noise level for the variogram's
        eiv = np.maximum(np.asarray(scales[i]) ** 2 - float(sigma_fit[i]) ** 2, 0.0)
        floor = float(problem.floors[i])
        noise.append((np.sqrt(eiv + max(sd, floor) ** 2), r, eiv, floor))
    for i, run in enumerate(campaign.runs):
        y = np.asarray(problem.y[i])
        f = np.asarray(preds[i])
        if run.kind == "hysteresis":
            tau = np.asarray(inputs[i].torque_Nm)
            d_f, d_t = np.gradient(f), np.gradient(tau)
            eps = 1e-6 * (np.max(np.abs(tau)) + 1e-12)
            sens = d_f * d_t / (d_t**2 + eps**2)
            views.append(RunView(
                name=run.name, kind=run.kind, time_s=np.asarray(run.time_s), residual=y - f,
                scale=noise[i][0], rho=noise[i][1], drive_torque_Nm=tau,
                mesh_torque_Nm=np.asarray(mesh[i]), measured_angle_rad=np.asarray(run.angle_rad),
                output_angle_rad=None, speed_rad_s=0.0, direction=0.0,
                loading_rate_Nm_per_s=run.loading_rate_Nm_per_s, sensitivity=sens,
                design=np.asarray(problem.design[i]), eiv_var=noise[i][2], floor=noise[i][3],
            ))
        else:
            n = len(run)
            phi = np.asarray(run.output_angle_rad)
            time = np.asarray(inputs[i].time_s)
            views.append(RunView(
                name=run.name, kind=run.kind, time_s=time, residual=y - f, scale=noise[i][0],
                rho=noise[i][1], drive_torque_Nm=np.full(n, run.torque_Nm * run.direction),
                mesh_torque_Nm=np.asarray(mesh[i]), measured_angle_rad=phi, output_angle_rad=phi,
                speed_rad_s=run.speed_rpm * 2 * np.pi / 60, direction=float(run.direction),
                loading_rate_Nm_per_s=None, sensitivity=np.zeros(n), design=np.asarray(problem.design[i]),
                eiv_var=noise[i][2], floor=noise[i][3],
            ))
    if robust and any(moves_in_jumps(*jump_reading(v.residual, v.floor)) for v in views):
        # the fit's physics are the nuisance of a winsorised test as well: the least-squares fit
        # put them where the jumps pull, and a refit robust to the jumps may move them
        directions = directions if directions is not None else _physics_directions(problem, u)
        for i, v in enumerate(views):
            jac = [np.asarray(a, float).reshape(len(v.residual), -1) for a in directions[1][i].values()]
            views[i] = replace(v, physics_design=np.concatenate(jac, axis=1) if jac else np.zeros((len(v.residual), 0))
                               ).with_robust_noise(v.residual)
    return FitContext(campaign=campaign, effects=dict(effects), map_result=map_result, runs=tuple(views),
                      rated_torque_Nm=campaign.reducer.rated_torque_Nm, computed_directions=directions)
