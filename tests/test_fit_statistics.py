"""Statistical behaviour of the fit on SYNTHETIC campaigns from the virtual bench: does the MAP
recover the truth, do the intervals cover what they claim, does the AR(1) likelihood matter,
what can a TE-only campaign tell apart, and does bad input end in a clear error.

Every campaign here is SYNTHETIC (``tests/benches/stat_*.toml``), simulated with the base
physics (linear spring, Dahl friction, smooth backlash) and realistic sensors (1″ encoder
steps, extra angle noise, 1.5 N·m torque noise). The fit is the base model with a free initial
friction state, MAP from two starts, intervals from the Laplace approximation — see
:func:`credible_intervals` to switch them to posterior HDIs once the sampler is in.

Seeds are fixed *before* looking at the results and never tuned; the pass criteria are set
from the binomial spread of a perfectly calibrated method (the false-alarm rate of each
criterion is written next to it). Every campaign of one test has the same shape (same runs,
same lengths, same model), so the fit compiles once per shape (six shapes, ~15–25 s each);
the whole file takes about three minutes on an idle two-core machine (~160 s of CPU).
"""

import dataclasses
from pathlib import Path
from statistics import NormalDist

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit import InputError
from torsionfit.bench import load_bench, simulate
from torsionfit.fit import NoiseOptions, build_problem, fit_map, log_density
from torsionfit.fit._contraction import prior_dominated, prior_dominated_note
from torsionfit.io import Campaign
from torsionfit.model import CampaignModel, NoBacklash, model_with_effects

BENCHES = Path(__file__).parent / "benches"
WHITE = BENCHES / "stat_rv_white.toml"  # hysteresis + 2 TE runs, 1″ white angle noise
AR1 = BENCHES / "stat_rv_ar1.toml"  # the same runs, AR(1) angle noise (3″, ρ = 0.9)
TE_ONLY = BENCHES / "stat_te_only.toml"  # TE runs at three loads, both directions, no gap

#: the physical parameters of the base model whose intervals are checked
PHYSICAL = ("stiffness", "friction_torque", "dahl_torque", "gap", "gap_torque")

#: where the intervals come from: "laplace" (MAP ± z·sd in the unconstrained space, mapped
#: back) or "posterior" (HDIs of emcee draws). Switch here once the sampler is in; the
#: calibration tests then need far fewer campaigns or a longer time budget.
INTERVAL_SOURCE = "laplace"

_TO_VALUE = {"positive": np.exp, "real": lambda u: u, "signed_unit": np.tanh}


# --- helpers -----------------------------------------------------------------------------------
def fit_campaign(campaign: Campaign, noise: NoiseOptions = NoiseOptions(), seed: int = 0, model=None):
    """MAP fit of ``campaign`` with the base model (free initial friction state) unless a
    ``model`` is given."""
    if model is None:
        model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                                   free_friction_start=True)
    problem = build_problem(campaign, model, noise)
    return fit_map(problem, [r.name for r in campaign.runs], n_starts=2, seed=seed)


def credible_intervals(result, level: float, names=PHYSICAL) -> dict[str, tuple[float, float]]:
    """Central ``level`` interval (natural scale) of each scalar model parameter in ``names``,
    from the source chosen by :data:`INTERVAL_SOURCE`."""
    if INTERVAL_SOURCE == "laplace":
        return laplace_intervals(result, level, names)
    if INTERVAL_SOURCE == "posterior":
        return posterior_hdi_intervals(result, level, names)
    raise ValueError(f"unknown INTERVAL_SOURCE {INTERVAL_SOURCE!r}")


def _constraints(problem) -> dict[str, str]:
    return {p.name: p.constraint for p in problem.physics if p.size == 1}


def laplace_intervals(result, level, names=PHYSICAL):
    """u_MAP ± z·sd per parameter, mapped back through its bijection (exp for positive ones)."""
    z = NormalDist().inv_cdf(0.5 + level / 2)
    constraint = _constraints(result.problem)
    out = {}
    for name in names:
        i = result.names.index(name)
        lo, hi = result.u[i] - z * result.sd[i], result.u[i] + z * result.sd[i]
        out[name] = (float(_TO_VALUE[constraint[name]](lo)), float(_TO_VALUE[constraint[name]](hi)))
    return out


def posterior_hdi_intervals(result, level, names=PHYSICAL, seed=0):
    """Highest-density intervals of emcee draws on the natural scale (not used while
    INTERVAL_SOURCE is "laplace"; emcee on a hundred campaigns is far beyond the CI budget)."""
    from torsionfit.sample import run_sampler

    draws = run_sampler(result.problem, result, seed=seed, progress=False).flat()
    constraint = _constraints(result.problem)
    out = {}
    for name in names:
        x = np.sort(_TO_VALUE[constraint[name]](draws[:, result.names.index(name)]))
        k = max(1, int(np.ceil(level * len(x))))
        widths = x[k - 1:] - x[:len(x) - k + 1]
        j = int(np.argmin(widths))
        out[name] = (float(x[j]), float(x[j + k - 1]))
    return out


def covered(result, truth: dict, level: float, names=PHYSICAL) -> np.ndarray:
    """Boolean per parameter: is the true value inside its ``level`` interval?"""
    iv = credible_intervals(result, level, names)
    return np.array([iv[n][0] <= float(truth[n]) <= iv[n][1] for n in names])


def varied_bench(bench, rng, spread=0.2, names=PHYSICAL):
    """The bench with each named truth value scaled by an independent U(1 − spread, 1 + spread)."""
    truth = dict(bench.truth)
    for name in names:
        truth[name] = float(truth[name]) * rng.uniform(1 - spread, 1 + spread)
    return dataclasses.replace(bench, truth=truth)


def coverage_table(hits: np.ndarray, names=PHYSICAL) -> str:
    per = ", ".join(f"{n} {100 * h:.0f} %" for n, h in zip(names, hits.mean(axis=0)))
    return f"pooled {100 * hits.mean():.1f} % over {hits.shape[0]} campaigns × {hits.shape[1]} parameters ({per})"


def joint_offset_correlation(result, name: str) -> float:
    """Laplace correlation between model parameter ``name`` (its u) and the first linear
    parameter (for a TE-only campaign: TE_0, the shared TE zero).

    The linear parameters are profiled out of u: β̂(u) solves weighted least squares, and
    under the flat prior β | u ~ N(β̂(u), A⁻¹). With u ~ N(u*, Σ): cov(u, β) = Σ Jᵀ and
    cov(β) = A⁻¹ + J Σ Jᵀ, J = dβ̂/du."""
    problem, u = result.problem, jnp.asarray(result.u)
    jac = np.asarray(jax.jacfwd(lambda v: problem.profile(v)[1])(u))
    _, rho = problem.noise_values(u)
    *_, scales = problem.profile(u, return_scales=True)
    a = sum(np.asarray(w.T @ w) for w in
            (problem.whiten(x, scales[r], rho[r]) for r, x in enumerate(problem.design)))
    cov_u = result.cov
    cov_ub = cov_u @ jac.T
    cov_b = np.linalg.inv(a) + jac @ cov_u @ jac.T
    i = result.names.index(name)
    return float(cov_ub[i, 0] / np.sqrt(cov_u[i, i] * cov_b[0, 0]))


def laplace_correlation(result, a: str, b: str) -> float:
    i, j = result.names.index(a), result.names.index(b)
    return float(result.cov[i, j] / np.sqrt(result.cov[i, i] * result.cov[j, j]))


# --- 1. parameter recovery ---------------------------------------------------------------------
#: seeds of the recovery test, fixed in advance
RECOVERY_SEEDS = range(10)
#: a parameter must be inside its 95 % interval on at least this many of the 10 seeds. With
#: exact 95 % coverage, P(≤ 7 of 10) = 1.2 % per parameter (≈ 5 % for all five); resampling
#: 300 simulated campaigns of this bench with today's fit (friction a little overconfident,
#: see the calibration test) gives 9.5 %. "≥ 9 of 10" would fail a perfectly calibrated fit
#: on ~37 % of seed sets (8.6 % per parameter), today's fit on 39 %.
RECOVERY_MIN_COVERED = 9  # issue 3: every parameter inside its 95 % interval on ≥ 9 of 10 seeds
#: and the intervals must be informative (guards against coverage by vagueness): the median
#: relative half-width of the 95 % interval per parameter below these bounds, about 3× what
#: the fit gives today (0.17 %, 2.7 %, 23 %, 0.8 %, 7.7 %)
RECOVERY_MAX_HALF_WIDTH = {"stiffness": 0.005, "friction_torque": 0.1, "dahl_torque": 0.6,
                           "gap": 0.03, "gap_torque": 0.25}


@pytest.mark.slow
def test_parameter_recovery_on_ten_seeds():
    """Base-model campaign (one hysteresis loop + TE forward at 380 N·m and backward at
    190 N·m), 1″ white angle noise + quantisation + 1.5 N·m torque noise: every physical
    parameter is inside its 95 % interval on at least 9 of 10 seeds (the issue's rule; with exact
    95 % coverage a fixed seed set meets it for all five parameters only ~63 % of the time — these
    seeds were fixed before any result was seen), the intervals are
    narrow enough to mean something, and every fit converged."""
    bench = load_bench(WHITE)
    hits, half_widths, errors, converged = [], [], [], []
    for seed in RECOVERY_SEEDS:
        sim = simulate(bench, seed=seed)
        result = fit_campaign(sim.campaign, seed=seed)
        converged.append(result.converged)
        hits.append(covered(result, sim.truth, 0.95))
        iv = credible_intervals(result, 0.95)
        truth = np.array([float(sim.truth[n]) for n in PHYSICAL])
        half_widths.append([(iv[n][1] - iv[n][0]) / 2 / t for n, t in zip(PHYSICAL, truth)])
        errors.append([float(result.values[n]) / t - 1 for n, t in zip(PHYSICAL, truth)])
    hits, half_widths, errors = np.array(hits), np.array(half_widths), np.array(errors)
    counts = dict(zip(PHYSICAL, hits.sum(axis=0).tolist()))
    med_hw = dict(zip(PHYSICAL, np.round(np.median(half_widths, axis=0), 4).tolist()))
    max_err = dict(zip(PHYSICAL, np.round(np.max(np.abs(errors), axis=0), 4).tolist()))
    summary = (f"covered (of {len(hits)}): {counts}; median relative half-width of the 95 % "
               f"interval: {med_hw}; largest relative MAP error: {max_err}; converged {sum(converged)}/{len(hits)}")
    print("\n[recovery] " + summary)
    assert all(converged), summary
    assert all(c >= RECOVERY_MIN_COVERED for c in counts.values()), summary
    assert all(med_hw[n] < RECOVERY_MAX_HALF_WIDTH[n] for n in PHYSICAL), summary


# --- 2. calibration ----------------------------------------------------------------------------
CALIBRATION_CAMPAIGNS = 100
CALIBRATION_SEEDS = range(100, 100 + CALIBRATION_CAMPAIGNS)
TRUTH_RNG_SEED = 2024


@pytest.mark.slow
def test_ninety_percent_intervals_are_calibrated():
    """100 campaigns of the white-noise bench, each with its own seed and its own truth (all
    five physical parameters scaled by U(0.8, 1.2)): the 90 % intervals cover the truth
    85–95 % of the time, pooled over the five parameters (≈ 500 intervals, correlated —
    stiffness and gap most: the pooled coverage of 100 campaigns spreads by ≈ 1.5 %, measured
    by resampling 300 campaigns, so the band is about ±3 sd). A loose per-parameter floor
    (75 %, 5 sd below 90 % for 100 campaigns) catches one badly calibrated parameter that the
    pool would hide. Measured: pooled 91.2 %, friction 94 % (≈ 85 % while the drive torque's
    error was counted sample by sample instead of as a latent line per ramp), gap_torque 88 %."""
    bench = load_bench(WHITE)
    rng = np.random.default_rng(TRUTH_RNG_SEED)
    hits, converged = [], 0
    for seed in CALIBRATION_SEEDS:
        sim = simulate(varied_bench(bench, rng), seed=seed)
        result = fit_campaign(sim.campaign, seed=seed)
        converged += result.converged
        hits.append(covered(result, sim.truth, 0.90))
    hits = np.array(hits)
    message = f"90 % intervals: {coverage_table(hits)}; converged {converged}/{len(hits)}"
    print("\n[calibration] " + message)
    assert 0.85 <= hits.mean() <= 0.95, message
    assert np.all(hits.mean(axis=0) >= 0.75), message


#: campaigns of the encoder-step case (the white-noise bench's shape: its programs are reused)
STEP_ONLY_SEEDS = range(500, 520)


@pytest.fixture(scope="module")
def step_only_hits():
    """The white-noise bench without its extra angle noise (the encoder's 1″ steps and the
    1.5 N·m torque noise are all the noise there is), 20 campaigns of one reducer: whether each
    physical parameter's 95 % interval covers the truth, (20, 5)."""
    bench = load_bench(WHITE)
    bench = dataclasses.replace(bench, noise=dataclasses.replace(bench.noise, angle_sd_arcsec=0.0))
    hits = []
    for seed in STEP_ONLY_SEEDS:
        sim = simulate(bench, seed=seed)
        hits.append(covered(fit_campaign(sim.campaign, seed=seed), sim.truth, 0.95))
    hits = np.array(hits)
    print(f"\n[encoder step] 95 % intervals, encoder steps and torque noise only: {coverage_table(hits)}")
    return hits


@pytest.mark.slow
def test_friction_intervals_hold_when_the_angle_noise_is_below_the_encoder_step(step_only_hits):
    """The friction level's 95 % intervals cover the truth on at least 17 of 20 campaigns (a
    calibrated method fails that 1.6 % of the time). Here the denoised torque's error is most of
    the angle's: it is one line per ramp (the smoother's error), and the fit carries it as a
    latent line per ramp. Counted sample by sample instead (the per-sample variance it was
    before), friction covered 10 of 20, its z-scores' sd 2.5; now 18 of 20."""
    assert step_only_hits[:, PHYSICAL.index("friction_torque")].sum() >= 17, coverage_table(step_only_hits)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "known: with the 1″ encoder steps as the only angle noise, the gap's closing torque is read off "
    "a few samples per crossing (4 Hz at 20 N·m/s: 5 N·m apart across a 5 N·m transition) whose "
    "quantisation errors the likelihood counts as independent noise of sd step/√12; one reducer "
    "measured again and again repeats one pattern of them, and gap_torque comes out 2.5 % high in "
    "all 20 campaigns at an sd of 1 % (with 0.01″ steps the bias is gone)"))
def test_gap_closing_torque_intervals_hold_when_the_angle_noise_is_below_the_encoder_step(step_only_hits):
    """gap_torque's 95 % intervals should cover the truth on at least 17 of 20. Measured: 0 of 20
    (before the torque error was carried per ramp, its per-sample variance widened the interval
    over the bias: 20 of 20)."""
    assert step_only_hits[:, PHYSICAL.index("gap_torque")].sum() >= 17, coverage_table(step_only_hits)


@pytest.mark.slow
def test_with_finer_encoder_steps_the_gap_closing_torque_is_unbiased():
    """The control of the expected failure above: the same bench with 0.01″ encoder steps (the
    torque noise as before). gap_torque's bias goes (mean within 0.5 % of the truth over five
    campaigns) and each 95 % interval holds it: the 1″ steps' quantisation made it."""
    bench = load_bench(WHITE)
    bench = dataclasses.replace(bench, noise=dataclasses.replace(bench.noise, angle_sd_arcsec=0.0),
                                instrument=dataclasses.replace(bench.instrument, encoder_resolution_arcsec=0.01))
    ratios, hits = [], []
    for seed in list(STEP_ONLY_SEEDS)[:5]:
        sim = simulate(bench, seed=seed)
        result = fit_campaign(sim.campaign, seed=seed)
        ratios.append(float(np.exp(result.u[result.names.index("gap_torque")])) / float(sim.truth["gap_torque"]))
        hits.append(covered(result, sim.truth, 0.95, names=("gap_torque",))[0])
    assert abs(np.mean(ratios) - 1.0) < 0.005 and all(hits), (ratios, hits)


# --- 3. correlated noise -----------------------------------------------------------------------
AR1_CAMPAIGNS = 100
AR1_SEEDS = range(300, 300 + AR1_CAMPAIGNS)
#: the iid fit fails so clearly that the first 30 of the same campaigns show it
IID_CAMPAIGNS = 30


@pytest.fixture(scope="module")
def ar1_simulations():
    """100 campaigns of the AR(1)-noise bench (ρ = 0.9, sd 3″), truth varied as above."""
    bench = load_bench(AR1)
    rng = np.random.default_rng(TRUTH_RNG_SEED + 1)
    return [simulate(varied_bench(bench, rng), seed=seed) for seed in AR1_SEEDS]


def _coverage(simulations, noise):
    hits, converged = [], 0
    for seed, sim in zip(AR1_SEEDS, simulations):
        result = fit_campaign(sim.campaign, noise, seed=seed)
        converged += result.converged
        hits.append(covered(result, sim.truth, 0.90))
    return np.array(hits), converged


@pytest.mark.slow
def test_ar1_likelihood_keeps_intervals_calibrated_under_correlated_noise(ar1_simulations):
    """AR(1) angle noise (ρ = 0.9, ten times the quantisation floor) fitted with the AR(1)
    likelihood on every run: the 90 % intervals cover 85–95 % (pooled, 100 campaigns × 5;
    spread of the pooled coverage ≈ 1.8 %, measured by resampling 200 campaigns)."""
    hits, converged = _coverage(ar1_simulations, NoiseOptions(ar1=True))
    message = f"ar1=True, 90 % intervals: {coverage_table(hits)}; converged {converged}/{len(hits)}"
    print("\n[ar1] " + message)
    assert 0.85 <= hits.mean() <= 0.95, message


@pytest.mark.slow
def test_iid_likelihood_is_overconfident_under_correlated_noise(ar1_simulations):
    """The same campaigns fitted as if the noise were independent: the intervals are several
    times too narrow (a run of N samples with ρ = 0.9 carries about N·(1 − ρ)/(1 + ρ) ≈ N/19
    independent pieces of information), and the 90 % intervals cover well below 85 %."""
    hits, converged = _coverage(ar1_simulations[:IID_CAMPAIGNS], NoiseOptions(ar1=False))
    message = f"ar1=False, 90 % intervals: {coverage_table(hits)}; converged {converged}/{len(hits)}"
    print("\n[iid] " + message)
    assert hits.mean() < 0.75, message


# --- 4. identifiability ------------------------------------------------------------------------
def _te_campaign(sim, directions):
    runs = tuple(r for r in sim.campaign.runs if r.direction in directions)
    return dataclasses.replace(sim.campaign, runs=runs)


def _gap_free_model(campaign):
    return CampaignModel(run_kinds=tuple(r.kind for r in campaign.runs), backlash=NoBacklash(),
                         free_friction_start=True)


@pytest.mark.slow
def test_te_only_friction_needs_both_directions():
    """What a TE-only campaign can tell apart (model of DESIGN §1.2, gap-free mesh).

    A TE run under constant load τ in direction d reads TE = TE_0 + C(d·(|τ| + T_f)), with one
    zero TE_0 shared by every TE run. With a linear spring, forward runs read
    TE_0 + τ/K + T_f/K: loads 95, 190 and 380 N·m pin the slope 1/K, but T_f/K is the same
    constant in every run and TE_0 takes it whole. So with one direction:

    * friction is *not* confounded with stiffness — K is sharp from the slope, and
      corr(log T_f, log K) ≈ 0 — but with the TE zero: TE_0 + T_f/K is all the data see;
    * the likelihood is exactly flat in T_f (it moves by < 10⁻⁶ nats when T_f changes 20×),
      the posterior of T_f is its prior (Laplace sd of log T_f = the prior's 2.0: a 95 %
      interval spanning a factor of ~2500), and corr(T_f, TE_0) ≈ −1.

    Backward runs read TE_0 − (τ + T_f)/K: forward minus backward is 2(τ + T_f)/K, whose
    intercept over the loads gives T_f. Adding the reverse direction shrinks the friction
    interval by more than 20× (to a few %), covers the truth, and breaks the friction–zero
    correlation. It leaves a strong *positive* corr(log T_f, log K) (≈ 0.9): T_f is the
    intercept/slope ratio of a line extrapolated from 95–380 N·m to −T_f, so both come from
    the same slope — a benign correlation with narrow marginals, reported but not asserted.

    With a gap in the model (smooth backlash, gap closed at loads ≫ τ_β) the gap's θ_g = ±β/2
    enters exactly like T_f/K: even both directions give only 2T_f/K + β, so friction and gap
    trade off (corr(log T_f, log β) ≈ −1) and friction is back to its prior. Separating
    friction from lost motion needs the hysteresis loop (the sign of motion, not of load).
    """
    bench = load_bench(TE_ONLY)
    sim = simulate(bench, seed=7)
    t_f = float(sim.truth["friction_torque"])

    forward = _te_campaign(sim, (1,))
    one = fit_campaign(forward, NoiseOptions(ar1=False), seed=7, model=_gap_free_model(forward))
    both = fit_campaign(sim.campaign, NoiseOptions(ar1=False), seed=7, model=_gap_free_model(sim.campaign))

    i_f, i_k = one.names.index("friction_torque"), one.names.index("stiffness")
    prior_sd_f = float(one.problem.prior_sd[i_f])
    sd_one, sd_both = one.sd[i_f], both.sd[i_f]
    corr_fk = (laplace_correlation(one, "friction_torque", "stiffness"),
               laplace_correlation(both, "friction_torque", "stiffness"))
    corr_f0 = (joint_offset_correlation(one, "friction_torque"), joint_offset_correlation(both, "friction_torque"))
    iv_one = credible_intervals(one, 0.95, ("friction_torque", "stiffness"))
    iv_both = credible_intervals(both, 0.95, ("friction_torque", "stiffness"))

    # the likelihood (log-density less the prior) as a function of log T_f, one direction
    def log_lik(result, shift):
        u = jnp.asarray(result.u).at[i_f].add(shift)
        return float(log_density(result.problem, u) - result.problem.log_prior(u))

    flat = max(abs(log_lik(one, s) - log_lik(one, 0.0)) for s in (-1.5, 1.5))
    steep = min(abs(log_lik(both, s) - log_lik(both, 0.0)) for s in (-0.2, 0.2))

    message = (
        f"friction 95 % interval one direction {iv_one['friction_torque']} N·m (sd log {sd_one:.3f}, prior sd "
        f"{prior_sd_f:.2f}), both {iv_both['friction_torque']} N·m (sd log {sd_both:.4f}), truth {t_f} N·m; "
        f"shrink ×{sd_one / sd_both:.1f}; corr(T_f, TE_0) one {corr_f0[0]:+.4f} both {corr_f0[1]:+.3f}; "
        f"corr(log T_f, log K) one {corr_fk[0]:+.3f} both {corr_fk[1]:+.3f}; sd log K one {one.sd[i_k]:.5f} "
        f"both {both.sd[i_k]:.5f}; |Δ log lik| over T_f ×e^±1.5 (one) {flat:.2e}, over T_f ×e^±0.2 (both) {steep:.1f}"
    )
    print("\n[identifiability] " + message)
    # one direction: friction is its prior, absorbed by the TE zero; stiffness is sharp
    assert flat < 1e-6, message
    assert sd_one > 0.95 * prior_sd_f, message
    assert corr_f0[0] < -0.99, message
    assert abs(corr_fk[0]) < 0.1, message
    assert one.sd[i_k] < 0.01, message
    # both directions: friction pinned, the TE zero no longer takes it
    assert sd_both < sd_one / 20, message
    assert iv_both["friction_torque"][0] <= t_f <= iv_both["friction_torque"][1], message
    assert abs(corr_f0[1]) < 0.3, message
    assert steep > 10.0, message

    # with a gap in the model, both directions still cannot split friction from the gap
    gap = fit_campaign(sim.campaign, NoiseOptions(ar1=False), seed=7,
                       model=model_with_effects([r.kind for r in sim.campaign.runs], {}, bench.reducer.rated_torque_Nm))
    corr_fg = laplace_correlation(gap, "friction_torque", "gap")
    sd_gap_f = gap.sd[gap.names.index("friction_torque")]
    gap_message = f"with a gap in the model: corr(log T_f, log gap) {corr_fg:+.3f}, sd log T_f {sd_gap_f:.3f}"
    print("[identifiability] " + gap_message)
    assert corr_fg < -0.9, gap_message
    assert sd_gap_f > 0.5 * prior_sd_f, gap_message

    # what a fit says of it (fit/_contraction.py, on Laplace draws): one direction leaves the
    # friction its prior's and names it; both directions inform it; the stiffness always
    rng = np.random.default_rng(0)
    found = [prior_dominated(r.problem, rng.multivariate_normal(np.asarray(r.u), np.asarray(r.cov), size=4000))
             for r in (one, both)]
    # the forward runs each re-zeroed (a zero group of its own): the zeros take the twist whole
    rezeroed = dataclasses.replace(forward, runs=tuple(dataclasses.replace(r, zero_group=r.name) for r in forward.runs))
    alone = fit_campaign(rezeroed, NoiseOptions(ar1=False), seed=7, model=_gap_free_model(rezeroed))
    found.append(prior_dominated(alone.problem, rng.multivariate_normal(np.asarray(alone.u), np.asarray(alone.cov),
                                                                        size=4000)))
    print(f"[identifiability] prior-dominated: one direction {found[0]}, both {found[1]}, each run re-zeroed {found[2]}")
    assert "friction_torque" in found[0] and "stiffness" not in found[0], found[0]
    assert "friction_torque" not in found[1] and "stiffness" not in found[1], found[1]
    assert "stiffness" in found[2] and "friction_torque" in found[2], found[2]
    assert "friction_torque" in prior_dominated_note(found[0], one.problem)


# --- 5. bad input ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def white_campaign():
    return simulate(load_bench(WHITE), seed=0).campaign


def _replace_run(campaign, index, **changes):
    runs = list(campaign.runs)
    runs[index] = dataclasses.replace(runs[index], **changes)
    return dataclasses.replace(campaign, runs=tuple(runs))


def _expect_input_error(campaign, run_name, match):
    with pytest.raises(InputError, match=match) as err:
        fit_campaign(campaign)
    text = str(err.value)
    assert "\n" not in text and run_name in text, text


def test_too_short_hysteresis_run_is_an_input_error(white_campaign):
    h = white_campaign.runs[0]
    short = _replace_run(white_campaign, 0, time_s=h.time_s[:8], torque_Nm=h.torque_Nm[:8], angle_rad=h.angle_rad[:8])
    _expect_input_error(short, h.name, "8 samples")


def test_too_short_te_run_is_an_input_error(white_campaign):
    te = white_campaign.runs[1]
    short = _replace_run(white_campaign, 1, output_angle_rad=te.output_angle_rad[:5], te_rad=te.te_rad[:5])
    _expect_input_error(short, te.name, "5 samples")


def test_run_that_never_loads_is_an_input_error(white_campaign):
    """Torque flat at zero (sensor noise only): the loop never opens."""
    h = white_campaign.runs[0]
    flat = np.random.default_rng(0).normal(0.0, 1.5, len(h))
    _expect_input_error(_replace_run(white_campaign, 0, torque_Nm=flat), h.name, "never loads")


def test_campaign_without_runs_is_an_input_error(white_campaign):
    with pytest.raises(InputError, match="no runs"):
        build_problem(dataclasses.replace(white_campaign, runs=()), CampaignModel(run_kinds=()))


@pytest.mark.parametrize("field", ["angle_rad", "torque_Nm", "length"])
def test_non_finite_or_ragged_hand_built_run_is_an_input_error(white_campaign, field):
    h = white_campaign.runs[0]
    if field == "length":
        bad = _replace_run(white_campaign, 0, angle_rad=h.angle_rad[:-5])
        match = "length|samples"
    else:
        values = getattr(h, field).copy()
        values[50] = np.nan
        bad = _replace_run(white_campaign, 0, **{field: values})
        match = "finite|NaN|nan value"
    _expect_input_error(bad, h.name, match)


def test_torque_error_variance_can_be_switched_off():
    """NoiseOptions.torque_error_variance=False: each hysteresis sample's innovation sd is the
    angle noise alone; on (the default) the denoised torque's error adds where the loop is steep
    — all of it without the latent torque lines, and with them (the default) only what the
    ramps' lines leave: on this bench's straight ramps, nothing."""
    campaign = simulate(load_bench(WHITE), seed=1).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    runs = [i for i, r in enumerate(campaign.runs) if r.kind == "hysteresis"]
    for flag, latent, expected in ((True, False, "widened"), (False, False, "none"), (True, True, "none")):
        problem = build_problem(campaign, model, NoiseOptions(torque_error_variance=flag), latent_torque=latent)
        # the noise above the encoder floor at ~0: σ is the floor, the torque's error shows
        u = jnp.concatenate([problem.prior_mean, jnp.full(problem.n_runs, -40.0), jnp.zeros(problem.n_ar1)])
        scales = problem.sample_scales(u)
        sigma = problem.sample_sigma(u)
        widened = max(float(jnp.max(scales[r] / sigma[r])) for r in runs)
        assert (widened > 2.0) if expected == "widened" else (widened < 1.0 + 1e-6), (flag, latent, widened)
