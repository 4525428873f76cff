"""Model selection for closing the loop (fast): the drift shapes, the linearised LOO against
brute-force leave-one-out, and the rule that picks the criterion."""

import re

import numpy as np
import pytest

from torsionfit.model import model_with_effects, te_input
from torsionfit.model._drift import WARM_UP_FRACTIONS
from torsionfit._errors import InputError


def test_warm_up_drift_is_the_linear_drift_plus_saturating_exponentials():
    model = model_with_effects(["transmission_error", "transmission_error"], {"thermal_drift": "warm_up"}, 380.0)
    names = [p.name for p in model.parameters()]
    assert "drift" in names and "drift_warmup" in names
    t = np.linspace(5.0, 105.0, 201)  # the run starts at 5 s: drift counts from its first sample
    phi = np.linspace(0.0, 2 * np.pi, 201)
    inputs = [te_input(phi, 100.0, 5.0, 1, t), te_input(phi, 100.0, 5.0, -1, t)]
    values = {p.name: np.zeros(p.size) if p.linear else 1.0 for p in model.parameters()}
    amps = np.arange(1.0, 1.0 + 2 * len(WARM_UP_FRACTIONS))
    values["drift"] = np.array([0.0, 2e-3])
    values["drift_warmup"] = amps
    comps = model.components(values, inputs)
    tau = 100.0 * np.asarray(WARM_UP_FRACTIONS)
    k = len(WARM_UP_FRACTIONS)
    for r in range(2):
        expected = values["drift"][r] * (t - 5.0) + (1 - np.exp(-(t - 5.0)[:, None] / tau[None, :])) @ amps[r * k:(r + 1) * k]
        np.testing.assert_allclose(np.asarray(comps[r]["drift"]), expected, rtol=1e-12, atol=1e-15)
    linear = model_with_effects(["transmission_error"], {"thermal_drift": True}, 380.0)
    assert [p.name for p in linear.parameters() if p.name.startswith("drift")] == ["drift"]
    with pytest.raises(InputError, match="thermal_drift"):
        model_with_effects(["transmission_error"], {"thermal_drift": "quadratic"}, 380.0)


def test_linearised_loo_is_exact_leave_one_out_for_a_linear_gaussian_model():
    """y = A a + X b + noise (σ = 1), a with a normal prior (precision through pseudo-rows),
    b flat: the closed form equals refitting without each sample."""
    from torsionfit.diagnose._selection import leverage

    rng = np.random.default_rng(4)
    n = 40
    a_cols, x = rng.normal(size=(n, 3)), rng.normal(size=(n, 2))
    prior_sd = np.array([0.5, 2.0, 1.0])
    y = a_cols @ np.array([0.3, -1.0, 0.5]) + x @ np.array([2.0, 1.0]) + rng.normal(size=n)
    # the profiled residual and its Jacobian in a: the flat b projected out
    q, _ = np.linalg.qr(x)
    proj = np.eye(n) - q @ q.T
    full = np.concatenate([a_cols, x], axis=1)
    prec = np.diag(np.concatenate([1 / prior_sd**2, np.zeros(2)]))
    coef = np.linalg.solve(full.T @ full + prec, full.T @ y)
    w = y - full @ coef
    jac = np.concatenate([-proj @ a_cols, np.diag(1 / prior_sd)], axis=0)
    h = leverage(jac, n, x)
    closed = -0.5 * np.log(2 * np.pi) + 0.5 * np.log1p(-h) - 0.5 * w**2 / (1 - h)
    brute = []
    for i in range(n):
        keep = np.arange(n) != i
        c = np.linalg.solve(full[keep].T @ full[keep] + prec, full[keep].T @ y[keep])
        var = 1.0 + full[i] @ np.linalg.solve(full[keep].T @ full[keep] + prec, full[i])
        brute.append(-0.5 * np.log(2 * np.pi * var) - 0.5 * (y[i] - full[i] @ c) ** 2 / var)
    np.testing.assert_allclose(closed, brute, rtol=1e-9)


def _score(linearised, psis=None, k=None, note=""):
    from torsionfit.diagnose._selection import Score

    return Score(linearised=np.asarray(linearised, float), psis=None if psis is None else np.asarray(psis, float),
                 pareto_k=None if k is None else np.asarray(k, float), good_k=0.6, psis_note=note,
                 lengths=(len(linearised) // 2, len(linearised) - len(linearised) // 2))


def test_the_rule_uses_psis_loo_only_when_every_pareto_k_is_good():
    from torsionfit.diagnose._selection import LINEARISED, PSIS, compare

    n = 100
    before = _score(np.full(n, -1.0), np.full(n, -1.1), np.full(n, 0.2))
    after = _score(np.full(n, -0.5), np.full(n, -0.6), np.full(n, 0.3))
    c = compare(before, after)
    assert c.criterion == PSIS and c.delta == pytest.approx(50.0)
    bad = _score(np.full(n, -0.5), np.full(n, -0.6), np.r_[np.full(n - 1, 0.3), 0.9])
    c = compare(before, bad)
    assert c.criterion == LINEARISED and c.delta == pytest.approx(50.0)
    assert "Pareto k > 0.60 at 1 of 100 samples" in c.reason
    # PSIS-LOO missing (Laplace draws far from the posterior, or not finite): the fallback, finite
    missing = _score(np.full(n, -0.5), note="the Laplace draws do not represent the posterior")
    assert "not computed" in compare(_score(np.full(n, -0.5)), before).reason
    c = compare(missing, before)
    assert c.criterion == LINEARISED and np.isfinite(c.delta) and np.isfinite(c.se)
    assert "do not represent the posterior" in c.reason


def test_small_leftovers_are_notes_and_large_ones_findings():
    from torsionfit.diagnose import DiagnoseOptions, Evidence
    from torsionfit.diagnose._loop import judge_leftovers

    options = DiagnoseOptions()  # findings: > 5 % of the residual variance and RMSE > 1.10 × noise
    small = Evidence("unexplained", 50.0, 2, -10.0, 0.007, "periodic in time with period 3.5 s")
    large = Evidence("unexplained", 900.0, 2, -190.0, 0.40, "periodic in the measured angle with period 61 arcsec")
    findings, notes = judge_leftovers([small, large], 1.8, 1.04, options)
    assert findings == [large]
    assert len(notes) == 1 and notes[0].startswith("periodic in time") and "0.7 %" in notes[0]
    # a large share of a residual already at the noise (RMSE within 10 % of it) is a note too
    findings, notes = judge_leftovers([large], 0.50, 0.49, options)
    assert findings == [] and "against the noise estimate 0.49″" in notes[0]
    assert judge_leftovers([], 3.0, 1.0, options) == ([], [])


def test_the_standard_error_counts_a_structured_difference_once():
    """A gain concentrated in one stretch of a run (a misfit absorbed there) is one piece of
    evidence, not hundreds: the block SE is far larger than the per-sample one; for independent
    per-sample differences the two agree."""
    from torsionfit.diagnose._selection import compare

    rng = np.random.default_rng(2)
    n = 4000
    noise = rng.normal(0.0, 0.05, n)
    bump = np.zeros(n)
    bump[1000:1200] = 0.1
    before = _score(np.zeros(n))
    c = compare(before, _score(noise + bump))
    per_sample = np.sqrt(n * np.var(noise + bump))
    assert c.se > 2.5 * per_sample
    c = compare(before, _score(noise))
    assert c.se == pytest.approx(np.sqrt(n * np.var(noise)), rel=0.35)


def _te_view(name, residual, design, sd=1.0):
    from torsionfit.diagnose import RunView

    n = len(residual)
    zeros = np.zeros(n)
    return RunView(name=name, kind="transmission_error", time_s=np.arange(n, dtype=float), residual=residual,
                   scale=np.full(n, sd), rho=0.0, drive_torque_Nm=zeros, mesh_torque_Nm=zeros,
                   measured_angle_rad=zeros, output_angle_rad=zeros, speed_rad_s=0.0, direction=1.0,
                   loading_rate_Nm_per_s=None, sensitivity=zeros, design=design, eiv_var=zeros, floor=0.0)


def test_a_signature_sees_level_differences_between_runs_that_share_their_zero():
    """Four runs with one shared zero (one design column for all): a level per run that follows
    a regressor constant within each run is a difference between runs — the joint test sees it;
    a regressor equal in every run is the zero itself and vanishes; on noise alone the statistic
    is an ordinary χ² draw (projected run by run, rounding left columns of ~1e-10 whose fit to
    the noise came out at log10 p −2685)."""
    from torsionfit.diagnose import regression_evidence

    rng = np.random.default_rng(5)
    n, speeds = 500, np.array([2.0, 6.0, 12.0, 12.0])
    directions = np.array([1.0, 1.0, 1.0, -1.0])
    shared_zero = np.ones((n, 1))
    level = 0.3 * directions * speeds / 12.0  # the speed effect, in noise sds
    views = [_te_view(f"r{i}", 0.7 + level[i] + rng.normal(size=n), shared_zero) for i in range(4)]
    cols = [np.full((n, 1), d * v) for d, v in zip(directions, speeds)]
    ev = regression_evidence("speed", views, cols, "")
    assert ev.dof == 1 and ev.log10_p < -20, ev
    coef = ev.details["coefficients"][0]
    assert coef == pytest.approx(0.3 / 12.0, rel=0.2)
    assert regression_evidence("same", views, [np.ones((n, 1))] * 4, "").dof == 0
    noise = [_te_view(f"r{i}", 0.7 + rng.normal(size=n), shared_zero) for i in range(4)]
    assert regression_evidence("speed", noise, cols, "").log10_p > -4
    # a run's own columns (local_design) are projected out in that run only
    from dataclasses import replace

    own = [replace(v, local_design=np.ones((n, 1))) for v in views]
    assert regression_evidence("speed", own, cols, "").dof == 0


def test_noise_estimate_is_the_residuals_not_the_torque_noise_model():
    """The noise estimate is the residual's own (variogram, floored, marginal over ρ): the fit's
    errors-in-variables variance — torque noise times a steep gap's slope — is not added, so the
    estimate cannot exceed the residual it was read from (on a measured loop it had: 2480″ against
    an RMSE of 1185″, and every leftover became a note), and it is capped at the residual's RMS."""
    from types import SimpleNamespace

    from torsionfit.diagnose._loop import noise_rmse_arcsec
    from torsionfit.units import ANGLE_UNITS

    arcsec = ANGLE_UNITS["arcsec"]
    n = 1000
    eiv = np.zeros(n)
    eiv[490:510] = (5000.0 * arcsec) ** 2  # the gap crossing
    residual = np.random.default_rng(0).normal(0.0, 3.0 * arcsec, n)
    run = SimpleNamespace(scale=np.sqrt(eiv + (2.0 * arcsec) ** 2), rho=0.6, eiv_var=eiv, residual=residual)
    assert noise_rmse_arcsec(SimpleNamespace(runs=[run])) == pytest.approx(2.0 / np.sqrt(1 - 0.36), rel=1e-9)
    # strongly correlated noise: the marginal overshoots the residual; the estimate stops at it
    steps = SimpleNamespace(scale=np.full(n, 2.0 * arcsec), rho=0.9, eiv_var=np.zeros(n), residual=residual)
    assert noise_rmse_arcsec(SimpleNamespace(runs=[steps])) == pytest.approx(np.sqrt(np.mean(residual**2)) / arcsec, rel=1e-9)


def test_noise_with_its_ar1_coefficient_at_the_bound_is_read_from_one_sample_increments():
    """White noise plus a misfit that changes within a few samples (a gap crossing's, as on the
    independent simulator's loops): the variogram rises from lag 1 to lag 2 faster than AR(1)
    noise allows, ρ stops at its bound, and σ/√(1 − ρ²) would call the whole residual noise (the
    cap). The estimate is the white noise one-sample increments allow, γ(1), a bound from below
    for the noise and above for the white part here; a note names the run. Below the bound
    nothing changes and no note is written."""
    from types import SimpleNamespace

    from torsionfit.diagnose._context import RHO_BOUND, variogram_noise
    from torsionfit.diagnose._loop import NOISE_AT_BOUND, noise_bound_note, noise_rmse_arcsec
    from torsionfit.units import ANGLE_UNITS

    arcsec = ANGLE_UNITS["arcsec"]
    rng = np.random.default_rng(3)
    n, white = 4000, 8.0 * arcsec
    t = np.arange(n)
    # bursts of a misfit that turns within ~3 samples, every 200 samples, and a slow swell
    misfit = 150.0 * arcsec * np.sin(2 * np.pi * t / 6.0) * (t % 200 < 12) + 60.0 * arcsec * np.sin(2 * np.pi * t / 400.0)
    residual = misfit + rng.normal(0.0, white, n)
    sd, rho = variogram_noise(residual)
    assert rho == RHO_BOUND
    run = SimpleNamespace(name="burst", scale=np.full(n, sd), rho=rho, eiv_var=np.zeros(n), residual=residual)
    noise = noise_rmse_arcsec(SimpleNamespace(runs=[run]))
    rms = np.sqrt(np.mean(residual**2)) / arcsec
    assert noise == pytest.approx(np.sqrt(0.5 * np.mean(np.diff(residual) ** 2)) / arcsec, rel=1e-9)
    assert white / arcsec < noise < 0.5 * rms
    assert noise_bound_note([run]).startswith(f"{NOISE_AT_BOUND} in burst")
    # the same noise alone: ρ below the bound, the marginal as before, no note
    plain_sd, plain_rho = variogram_noise(rng.normal(0.0, white, n))
    plain = SimpleNamespace(name="plain", scale=np.full(n, plain_sd), rho=plain_rho, eiv_var=np.zeros(n),
                            residual=rng.normal(0.0, white, n))
    assert plain_rho < RHO_BOUND and noise_bound_note([plain]) is None
    assert noise_rmse_arcsec(SimpleNamespace(runs=[plain])) == pytest.approx(white / arcsec, rel=0.05)


def test_a_residual_that_moves_in_jumps_gets_a_note_and_noise_does_not():
    """``jump_note``: a residual of encoder-level noise plus sparse steps (stick-slip, as the
    measured loops' block means show: increments' median ~2 encoder steps, their 99th percentile
    ~40×) is named, with both noise readings; white noise, AR(1) noise, noise on a smooth
    misfit (what a missing catalog effect leaves) and noise below the encoder step are not."""
    from types import SimpleNamespace

    from torsionfit.diagnose._loop import JUMPS, jump_note
    from torsionfit.units import ANGLE_UNITS

    arcsec = ANGLE_UNITS["arcsec"]
    rng = np.random.default_rng(11)
    n = 2000
    noise = rng.normal(0.0, 40.0 * arcsec, n)
    ar1 = np.zeros(n)
    for i in range(1, n):
        ar1[i] = 0.9 * ar1[i - 1] + rng.normal(0.0, 40.0 * arcsec)
    smooth = 800.0 * arcsec * np.sin(np.linspace(0.0, 6 * np.pi, n))
    steps = np.cumsum(np.where(rng.random(n) < 0.03, rng.normal(0.0, 1500.0 * arcsec, n), 0.0))
    steps -= np.mean(steps)

    def run(name, residual, step_arcsec=1.0):
        return SimpleNamespace(name=name, residual=residual, floor=step_arcsec * arcsec / np.sqrt(12.0))

    assert jump_note([run("white", noise), run("ar1", ar1), run("misfit", smooth + noise)]) is None
    # noise below the encoder step: the median increment is 0, the quantisation's steps are no jumps
    step = 20.0 * arcsec
    quantised = step * np.round(rng.normal(0.0, 0.3 * step, n) / step)
    assert np.median(np.abs(np.diff(quantised))) == 0.0
    assert jump_note([run("below the step", quantised, step_arcsec=20.0)]) is None
    note = jump_note([run("clean", noise), run("stick-slip", steps + noise)])
    assert note is not None and "clean" not in note, note
    robust, variogram = map(float, re.search(r"stick-slip ([0-9.]+)″ against ([0-9.]+)″", note).groups())
    assert 35.0 < robust < 50.0 and variogram > 2 * robust, note  # the noise is 40″ (× √2 in the increments)
    assert note.startswith(JUMPS) and "\n" not in note  # the residual figure's title finds it by JUMPS


def test_a_step_keeps_the_candidate_that_earns_the_most(monkeypatch):
    """Of a step's significant signatures (up to ``candidates_per_step``, strongest first) every
    one is refitted and the one that earns the most ELPD is kept; the others, earning or not, are
    listed as rejected; when none earns, the next batch is tried, up to ``max_candidates_first_step``
    refits at the base model's step and ``max_candidates_per_step`` at later ones. Stand-in fits and signatures: the rule alone."""
    from dataclasses import replace
    from types import SimpleNamespace

    from torsionfit.diagnose import Effect, _loop
    from torsionfit.diagnose._selection import Comparison
    from torsionfit.diagnose._signature import Evidence

    gains = {"strong": 40.0, "weaker": 90.0, "weakest": 5.0}  # ΔELPD of each extension; se 1

    class Stand(Effect):
        def __init__(self, name):
            self.name = name

        def signature(self, ctx, alpha):
            return Evidence(self.name, 0.0, 1, {"strong": -30.0, "weaker": -20.0, "weakest": -10.0}[self.name], 0.1, "")

        def extend(self, effects, evidence, ctx):
            return {**effects, self.name: True}

    catalog = tuple(Stand(n) for n in gains)
    calls = []

    def fit_with(campaign, effects, options, seed, warm=None, start_values=None):
        calls.append(tuple(effects))
        return SimpleNamespace(effects=dict(effects), context=SimpleNamespace(runs=()), score=tuple(effects),
                               rmse_arcsec=1.0, max_abs_arcsec=1.0, rmse_per_run={})

    def compare(before, after):
        new = set(after) - set(before)
        return Comparison(sum(gains[n] for n in new), 1.0, "stand-in", "")

    def signatures(ctx, options, added):
        return [] if added else [(e, e.signature(ctx, options.alpha)) for e in options.catalog]

    monkeypatch.setattr(_loop, "fit_with", fit_with)
    monkeypatch.setattr(_loop, "compare", compare)
    monkeypatch.setattr(_loop, "_signatures", signatures)
    monkeypatch.setattr(_loop, "noise_rmse_arcsec", lambda ctx: 1.0)
    monkeypatch.setattr(_loop, "_leftovers", lambda ctx, options, added, tried, trail: [])
    monkeypatch.setattr(_loop, "jump_note", lambda runs: None)
    d = _loop.diagnose(SimpleNamespace(), _loop.DiagnoseOptions(catalog=catalog), seed=0)
    assert [s.effect for s in d.steps] == ["weaker"]
    assert d.final.effects == {"weaker": True}
    assert [(s.effect, s.kept) for s in d.rejected] == [("strong", False), ("weakest", False)]
    assert calls == [(), ("strong",), ("weaker",), ("weakest",)]  # all three refitted, strongest first
    # one candidate per step: the strongest alone, kept because it earns its keep
    calls.clear()
    d = _loop.diagnose(SimpleNamespace(), _loop.DiagnoseOptions(catalog=catalog, candidates_per_step=1), seed=0)
    assert [s.effect for s in d.steps] == ["strong"] and calls == [(), ("strong",)]
    # at the base model's step, when none of a batch earns its keep, the next batch is tried, the
    # best of it kept, and no batch after it: two per batch, the first two short of the thresholds
    gains.update(strong=1.0, weaker=2.0, weakest=50.0, fourth=80.0, fifth=90.0)
    catalog = tuple(Stand(n) for n in gains)
    strength = {"strong": -30.0, "weaker": -20.0, "weakest": -10.0, "fourth": -9.0, "fifth": -8.0}
    for e in catalog:
        e.signature = lambda ctx, alpha, name=e.name: Evidence(name, 0.0, 1, strength[name], 0.1, "")
    calls.clear()
    options = _loop.DiagnoseOptions(catalog=catalog, candidates_per_step=2, max_candidates_first_step=4)
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    assert [s.effect for s in d.steps] == ["fourth"]
    assert calls == [(), ("strong",), ("weaker",), ("weakest",), ("fourth",)]
    assert [s.effect for s in d.rejected] == ["strong", "weaker", "weakest"]
    calls.clear()
    d = _loop.diagnose(SimpleNamespace(), replace(options, max_candidates_first_step=2), seed=0)
    assert d.steps == [] and calls == [(), ("strong",), ("weaker",)]
    # at a later step the next ones up to max_candidates_per_step (by default the batch alone)
    monkeypatch.setattr(_loop, "_signatures", lambda ctx, options, added: [
        (e, e.signature(ctx, options.alpha)) for e in options.catalog if e.name not in added])
    gains.update(strong=90.0, weaker=1.0, weakest=2.0, fourth=80.0, fifth=3.0)
    calls.clear()
    options = _loop.DiagnoseOptions(catalog=catalog, candidates_per_step=1, max_candidates_first_step=2,
                                    max_candidates_per_step=1)
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    assert [s.effect for s in d.steps] == ["strong"] and calls == [(), ("strong",), ("strong", "weaker")]
    d = _loop.diagnose(SimpleNamespace(), replace(options, max_candidates_per_step=3), seed=0)
    assert [s.effect for s in d.steps] == ["strong", "fourth"]


def test_an_effect_that_contains_another_is_kept_only_when_it_earns_its_keep_over_it(monkeypatch):
    """Where a step's refits of an effect and of one it contains (``Effect.nests``: the relays
    contain the held gap) both earn their keep, the larger is kept only when it earns its keep
    over the smaller; where the smaller does not earn its keep, the larger is kept as usual.
    Stand-in fits and signatures: the rule alone."""
    from types import SimpleNamespace

    from torsionfit.diagnose import Effect, _loop
    from torsionfit.diagnose._selection import Comparison
    from torsionfit.diagnose._signature import Evidence

    elpd = {"held": 60.0, "relays": 65.0}  # each fit's ELPD over the base model; se 1

    class Stand(Effect):
        def __init__(self, name, nests=()):
            self.name, self.nests = name, nests

        def signature(self, ctx, alpha):
            return Evidence(self.name, 0.0, 1, -20.0, 0.1, "")

        def extend(self, effects, evidence, ctx):
            return {**effects, self.name: True}

    catalog = (Stand("relays", nests=("held",)), Stand("held"))

    def fit_with(campaign, effects, options, seed, warm=None, start_values=None):
        return SimpleNamespace(effects=dict(effects), context=SimpleNamespace(runs=()), score=tuple(effects),
                               rmse_arcsec=1.0, max_abs_arcsec=1.0, rmse_per_run={})

    def compare(before, after):
        return Comparison(sum(elpd[n] for n in after) - sum(elpd[n] for n in before), 1.0, "stand-in", "")

    monkeypatch.setattr(_loop, "fit_with", fit_with)
    monkeypatch.setattr(_loop, "compare", compare)
    monkeypatch.setattr(_loop, "_signatures", lambda ctx, options, added: [] if added else [
        (e, e.signature(ctx, options.alpha)) for e in options.catalog])
    monkeypatch.setattr(_loop, "noise_rmse_arcsec", lambda ctx: 1.0)
    monkeypatch.setattr(_loop, "_leftovers", lambda ctx, options, added, tried, trail: [])
    monkeypatch.setattr(_loop, "jump_note", lambda runs: None)
    options = _loop.DiagnoseOptions(catalog=catalog, backward=False)
    # the relays gain 5 over the held gap (below the 10 a step must gain): the held gap is kept
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    assert [s.effect for s in d.steps] == ["held"] and d.final.effects == {"held": True}
    assert [(s.effect, s.kept) for s in d.rejected] == [("relays", False)]
    assert d.steps[0].delta_elpd == 60.0
    # they gain 40 over it: the relays are kept
    elpd["relays"] = 100.0
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    assert [s.effect for s in d.steps] == ["relays"]
    # the held gap alone does not earn its keep: the relays are kept, whatever they gain over it
    elpd.update(held=5.0, relays=12.0)
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    assert [s.effect for s in d.steps] == ["relays"]


def _robust_view(name, residual, design, physics=None):
    """A TE-like view with its noise read robustly as well (median increments), as
    ``fit_context(robust=True)`` makes; ``physics``: the fit's physics directions (none: (N, 0))."""
    from dataclasses import replace

    n = len(residual)
    view = replace(_te_view(name, residual, design), robust_scale=np.ones(n),
                   physics_design=np.zeros((n, 0)) if physics is None else physics)
    return view.renoised(residual)


def test_a_robust_signature_reads_through_jumps_and_holds_its_level():
    """Isolated jumps (8 % of the samples moved by ±60 noise sds, the bench's ``jump_share``):
    the least-squares test counts them as noise (the variogram's sd ~17×) and misses an effect
    of 0.25 sd; a robust view's test (the better of it and the winsorised one) finds it, and on
    noise with jumps alone its p-values hold their level. The residual is a least-squares fit's,
    whose physics parameter the jumps pulled: without that parameter among the nuisance the
    winsorised residual keeps its pull and the test rejects where nothing is missing."""
    from torsionfit.diagnose import regression_evidence

    rng = np.random.default_rng(17)
    n, reps = 800, 60
    t = np.linspace(-1.0, 1.0, n)
    design = np.stack([np.ones(n), t], axis=1)  # offset and drift: the fit's linear terms
    physics = t[:, None] ** 2  # a physics direction the fit absorbs (its "stiffness")
    # the missing effect's signature, what of it no refit of the terms above absorbs, unit sd
    basis = np.concatenate([design, physics], axis=1)
    effect = np.cos(4.0 * t) + np.sin(7.0 * t)
    effect = (effect - basis @ np.linalg.lstsq(basis, effect, rcond=None)[0])[:, None]
    effect /= np.std(effect)

    def residual(amplitude):
        jumps = np.where(rng.random(n) < 0.08, rng.choice([-60.0, 60.0], n), 0.0)
        y = rng.normal(size=n) + jumps + amplitude * effect[:, 0] + 0.4 * physics[:, 0]
        return y - basis @ np.linalg.lstsq(basis, y, rcond=None)[0]  # the least-squares fit's residual

    found = {"robust": 0, "least squares": 0}
    for _ in range(reps):
        e = residual(0.25)
        found["robust"] += regression_evidence("x", [_robust_view("r", e, design, physics)], [effect], "").log10_p < -3
        found["least squares"] += regression_evidence("x", [_te_view("r", e, design).renoised(e)], [effect], "").log10_p < -3
    assert found["robust"] >= 0.8 * reps and found["least squares"] <= 0.1 * reps, found

    p, p_blind = [], []
    along = effect + physics / np.std(physics)  # a signature with a part along the physics: most have one
    for _ in range(4 * reps):
        e = residual(0.0)
        p.append(10 ** regression_evidence("x", [_robust_view("r", e, design, physics)], [along], "").log10_p)
        p_blind.append(10 ** regression_evidence("x", [_robust_view("r", e, design)], [along], "").log10_p)
    p = np.array(p)
    # its level: at most 5 % of the p-values below 0.05 (binomial sd 1.4 % at 240 draws; fewer, as
    # the better of two tests Bonferroni-corrected is conservative), none far below, and not all near 1
    assert np.mean(p < 0.05) <= 0.10 and np.min(p) > 1e-4 and np.mean(p < 0.5) > 0.2, np.sort(p)[:5]
    # blind to the fit's physics, it rejects where nothing is missing
    assert np.mean(np.array(p_blind) < 0.05) > 0.3, np.sort(p_blind)[:5]


def test_a_robust_signature_still_sees_a_large_misfit_on_few_samples():
    """What a torque offset leaves: a large misfit where the loop is steep (the gap crossings), a
    few samples. The winsorised test weighs those samples as jumps (log10 p −15 here, against the
    least-squares test's −90); a robust view runs both, the least-squares one counts, and
    ``details["test"]`` says so."""
    from torsionfit.diagnose import regression_evidence
    from torsionfit.diagnose._signature import _test, log10_chi2_sf

    rng = np.random.default_rng(23)
    n = 800
    k = np.arange(n)
    crossings = sum(np.exp(-0.5 * ((k - c) / 2.0) ** 2) for c in (100, 300, 500, 700))
    slope = (crossings * np.array([1.0 if (i // 200) % 2 == 0 else -1.0 for i in k]))[:, None]
    residual = 12.0 * slope[:, 0] + rng.normal(size=n)
    design = np.ones((n, 1))
    view = _robust_view("r", residual, design)
    ev = regression_evidence("torque_offset", [view], [slope], "")
    assert ev.log10_p < -20 and ev.details["test"] == "least-squares", ev
    # the winsorised test alone: far weaker (log10 p −15 against −90 on this draw)
    _, stat, dof, _ = _test([view], [slope], robust=True)
    assert log10_chi2_sf(stat, dof) > ev.log10_p + 50, (log10_chi2_sf(stat, dof), ev.log10_p)
    # each test's own p is recorded; the evidence's is the better one, Bonferroni over the two
    by_test = ev.details["log10_p_by_test"]
    assert set(by_test) == {"least-squares", "winsorised"}, by_test
    assert by_test["winsorised"] == pytest.approx(log10_chi2_sf(stat, dof))
    assert ev.log10_p == pytest.approx(by_test["least-squares"] + np.log10(2.0))


def test_figure_titles_wrap_to_the_figure_width():
    """A leftover's description runs to several hundred characters on measured loops: one title
    line that long is cut off at both edges of the figure; it is wrapped, and cut with an
    ellipsis past its last line."""
    from torsionfit.diagnose._report import _title

    text = "; ".join(f"periodic in time with period {p} s in runs initial-pos1 (8.9 % of the residual variance)"
                     for p in range(10, 20))
    title = _title(text, width=150, lines=2)
    assert len(title.splitlines()) == 2 and all(len(line) <= 150 for line in title.splitlines())
    assert title.endswith("…") and title.replace("\n", " ").startswith(text[:200])
    assert _title("short", width=150) == "short"


def test_candidates_are_refitted_in_the_order_of_their_least_squares_test():
    """Where a residual moves in jumps, significance is the better of two tests, but the order in
    which candidates are refitted is the least-squares test's (with the evidence's own search
    corrections): the refit is judged by the Gaussian ELPD of every sample, whose gain the
    least-squares Δχ² predicts. Evidence tested by least squares alone keeps its own p."""
    from torsionfit.diagnose._loop import _gain_rank
    from torsionfit.diagnose._signature import Evidence

    def robust(ls, winsorised, search=0.0):
        p = min(ls, winsorised) + np.log10(2.0) + search
        return Evidence("x", 1.0, 1, p, 0.1, "", {"log10_p_by_test": {"least-squares": ls, "winsorised": winsorised}})

    # the winsorised test's strongest is not the least-squares one's
    strong_behind_jumps, strong_by_ls = robust(-2.0, -90.0), robust(-50.0, -30.0)
    assert strong_behind_jumps.log10_p < strong_by_ls.log10_p
    assert _gain_rank(strong_by_ls) < _gain_rank(strong_behind_jumps)
    assert _gain_rank(robust(-50.0, -30.0, search=0.7)) == pytest.approx(-50.0 + 0.7)
    alone = Evidence("x", 1.0, 1, -12.3, 0.1, "", {"log10_p_by_test": {"least-squares": -13.0}})
    assert _gain_rank(alone) == -12.3 and _gain_rank(Evidence("x", 0.0, 0, 0.0, 0.0, "")) == 0.0


def test_the_backward_check_drops_an_effect_a_later_one_made_redundant(monkeypatch):
    """The trail is greedy: an effect kept early (``drift``) can take a misfit a later one
    (``gap``) explains better. When the trail stops, each kept effect but the last is refitted
    out of the final model; the one that no longer earns its keep is dropped, the trail goes on
    with the room it leaves (``max_effects``), and never takes it again. Stand-in fits whose
    ELPD is a function of the set of effects: the rule alone."""
    from dataclasses import replace
    from types import SimpleNamespace

    from torsionfit.diagnose import _loop
    from torsionfit.diagnose._selection import Comparison

    def elpd(effects) -> float:
        e = set(effects)
        # drift explains what the gap explains, and less of it; with the gap it adds 2
        return (60.0 if "gap" in e else 40.0 if "drift" in e else 0.0) + (2.0 if {"gap", "drift"} <= e else 0.0) \
            + (30.0 if "creep" in e else 0.0) + (25.0 if "speed" in e else 0.0)

    catalog, calls, _ = _stand_in_trail(monkeypatch, {"drift": -30.0, "gap": -20.0, "creep": -10.0, "speed": -9.0}, elpd)
    # one candidate a step, room for two effects: drift (the strongest signature) then the gap
    options = _loop.DiagnoseOptions(catalog=catalog, candidates_per_step=1, max_candidates_first_step=1,
                                    max_candidates_per_step=1, max_effects=2)
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    # with the gap in, drift earns 2: dropped, and its room goes to creep; the check after that
    # refits the gap out (creep was the last step: compared with exactly the model without it)
    assert [s.effect for s in d.steps] == ["gap", "creep"], [s.effect for s in d.steps]
    assert d.final.effects == {"gap": True, "creep": True}
    assert [(r.effect, r.dropped) for r in d.removals] == [("drift", True), ("gap", False)]
    drop = d.removals[0]
    assert drop.delta_elpd == 2.0 and drop.without.effects == {"gap": True}
    assert ("drift", "gap") in calls and ("creep", "drift", "gap") not in calls  # never taken again
    assert calls.count(("creep",)) == 1  # the gap's backward check
    # off: the greedy trail as it was
    d = _loop.diagnose(SimpleNamespace(), replace(options, backward=False), seed=0)
    assert [s.effect for s in d.steps] == ["drift", "gap"] and d.removals == []
    # an effect that keeps earning is never dropped: the check refits it out once and stops
    monkeypatch.setattr(_loop, "compare", lambda before, after: Comparison(
        sum(20.0 for n in set(after) - set(before)) - sum(20.0 for n in set(before) - set(after)), 1.0, "stand-in", ""))
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    assert [s.effect for s in d.steps] == ["drift", "gap"]
    assert [(r.effect, r.dropped, r.delta_elpd) for r in d.removals] == [("drift", False, 20.0)]


def test_a_trail_at_its_limit_swaps_its_weakest_effect_for_a_stronger_one(monkeypatch):
    """At ``max_effects`` with a significant signature left, the kept effect that earns the
    least is refitted out and the candidate refitted in its place; the swap is kept when the new
    model earns its keep over the trail's, and the effect swapped out is not taken again.
    Stand-in fits whose ELPD adds up per effect: the rule alone."""
    from dataclasses import replace
    from types import SimpleNamespace

    from torsionfit.diagnose import _loop
    from torsionfit.diagnose._report import summary_text

    worth = {"drift": 15.0, "creep": 30.0, "gap": 60.0, "speed": 5.0}
    strength = {"drift": -30.0, "creep": -20.0, "gap": -10.0, "speed": -9.0}

    def elpd(effects):
        return sum(worth[n] for n in effects)

    catalog, calls, _ = _stand_in_trail(monkeypatch, strength, elpd)
    options = _loop.DiagnoseOptions(catalog=catalog, candidates_per_step=1,
                                    max_candidates_first_step=1, max_candidates_per_step=1, max_effects=2)
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    # greedy: drift then creep fill the room; drift still earns 15 with creep in, but the gap in
    # its place earns 45 over the pair: swapped; then nothing significant is left to swap in
    assert [s.effect for s in d.steps] == ["creep", "gap"], [s.effect for s in d.steps]
    assert d.final.effects == {"creep": True, "gap": True}
    assert [(r.effect, r.dropped, r.replaced_by) for r in d.removals] == [
        ("drift", False, ""), ("drift", True, "gap"), ("creep", False, "")]
    swap = d.removals[1]
    assert swap.swap_comparison.delta == 45.0 and swap.delta_elpd == 15.0 and swap.without.effects == {"creep": True}
    assert d.steps[-1].delta_elpd == 60.0 and d.steps[-1].before is swap.without
    assert ("drift", "gap") not in calls  # the effect swapped out is not taken again
    doc = {"rmse_base": 1.0, "steps": [], "rejected": [], "rmse_final": 1.0, "noise_estimate": 1.0, "added": [],
           "unexplained": False, "removals": [{"effect": "drift", "dropped": True, "replaced_by": "gap",
                                               "swap_delta_elpd": 45.0, "swap_delta_elpd_se": 1.0, "delta_elpd": 15.0,
                                               "delta_elpd_se": 1.0, "criterion": "stand-in", "rmse_without": 2.0,
                                               "rmse_with": 1.0}]}
    assert "- drift" in summary_text(doc) and "swapped out for gap (ΔELPD 45.0 ± 1.0 over the model with it)" in summary_text(doc)
    # a swap that does not earn its keep over the trail's model is tried and left
    worth["gap"] = 20.0
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    assert [s.effect for s in d.steps] == ["drift", "creep"]
    assert [s.effect for s in d.rejected][-1] == "gap" and d.rejected[-1].delta_elpd == 5.0
    # off: the trail stops at its limit
    worth["gap"] = 60.0
    d = _loop.diagnose(SimpleNamespace(), replace(options, swap=False), seed=0)
    assert [s.effect for s in d.steps] == ["drift", "creep"] and all(not r.replaced_by for r in d.removals)


def _stand_in_trail(monkeypatch, strength: dict, elpd):
    """Stand-in fits for the trail's rules: effects named by ``strength`` (their signatures'
    log10 p) whose fits' ELPD is ``elpd(effects)``. Returns (catalog, calls: the effect sets fitted)."""
    from types import SimpleNamespace

    from torsionfit.diagnose import Effect, _loop
    from torsionfit.diagnose._selection import Comparison
    from torsionfit.diagnose._signature import Evidence

    class Stand(Effect):
        def __init__(self, name):
            self.name = name

        def signature(self, ctx, alpha):
            return Evidence(self.name, 0.0, 1, strength[self.name], 0.1, "")

        def extend(self, effects, evidence, ctx):
            return {**effects, self.name: True}

    calls = []

    def fit_with(campaign, effects, options, seed, warm=None, start_values=None):
        calls.append(tuple(sorted(effects)))
        return SimpleNamespace(effects=dict(effects), context=SimpleNamespace(runs=()), score=tuple(effects),
                               rmse_arcsec=1.0, max_abs_arcsec=1.0, rmse_per_run={}, map_result=None)

    monkeypatch.setattr(_loop, "fit_with", fit_with)
    monkeypatch.setattr(_loop, "compare", lambda before, after: Comparison(elpd(after) - elpd(before), 1.0, "stand-in", ""))
    monkeypatch.setattr(_loop, "_signatures", lambda ctx, options, added: [
        (e, e.signature(ctx, options.alpha)) for e in options.catalog if e.name not in added])
    monkeypatch.setattr(_loop, "noise_rmse_arcsec", lambda ctx: 1.0)
    leftovers = []  # the effects refitted on the final model, as the trail tells the leftovers
    monkeypatch.setattr(_loop, "_leftovers", lambda ctx, options, added, tried, trail: leftovers.append((set(tried), None if trail is None else sorted(trail))) or [])
    monkeypatch.setattr(_loop, "jump_note", lambda runs: None)
    return tuple(Stand(n) for n in strength), calls, leftovers


def test_the_relay_gap_the_catalog_adds_is_bounded_by_half_the_loops_peak_torque():
    """The catalog's relay gap keeps its switches within half the hysteresis runs' largest applied
    torque of its centre (beyond, a relay switches in a loaded flank): the extension declares
    the bound, the start puts the signature's span inside it as a share, and the bound's option
    ``None`` gives the unbounded grid."""
    from types import SimpleNamespace

    from torsionfit.diagnose import GapRelays
    from torsionfit.diagnose._signature import Evidence
    from torsionfit.model import RELAY_FLANK_SHARE, RelayGapBacklash

    ctx = SimpleNamespace(hysteresis=[SimpleNamespace(drive_torque_Nm=np.array([0.0, 30.0, -42.0, 4.0])),
                                      SimpleNamespace(drive_torque_Nm=np.array([-4.0, 4.0]))])
    bounded, unbounded = GapRelays(), GapRelays(max_span_share=None)
    assert RELAY_FLANK_SHARE == 0.5 and bounded._bound_Nm(ctx) == pytest.approx(21.0) and unbounded._bound_Nm(ctx) is None

    def evidence(bound):
        return Evidence("gap_relays", 50.0, 28, -9.0, 0.3, "relays",
                        {"relay_span_Nm": 6.0, "max_span_Nm": bound, "hold_torque_Nm": 2.0})

    effects = {"distributed_friction": True, "gap_hold": {"centred": False}}
    assert bounded.extend(effects, evidence(21.0), ctx) == {"distributed_friction": True, "gap_relays": {"max_span_Nm": 21.0}}
    assert unbounded.extend(effects, evidence(None), ctx) == {"distributed_friction": True, "gap_relays": True}
    start = bounded.start_values(evidence(21.0))
    assert start["gap_relay_span_share"] == pytest.approx(6.0 / 21.0) and "gap_relay_span" not in start
    relays = RelayGapBacklash()
    assert np.argmax(np.concatenate([[0.0], start["gap_relay_logits"]])) == relays.nearest_relay(1 / 3, -1 / 3)
    assert unbounded.start_values(evidence(None))["gap_relay_span"] == 6.0
    model = model_with_effects(["hysteresis"], bounded.extend(effects, evidence(21.0), ctx), 20.0)
    assert model.backlash.max_span_Nm == 21.0


def test_a_step_a_later_one_replaced_is_not_reported_as_added():
    """The relays take the held gap's place: the trail keeps both steps, the final model and the
    report's ``added`` only the relays, with the replacement said."""
    from types import SimpleNamespace

    from torsionfit.diagnose._loop import Diagnosis
    from torsionfit.diagnose._report import summary_text

    def fitted(**effects):
        return SimpleNamespace(effects=effects)

    base = fitted()
    slip = fitted(distributed_friction=True)
    held = fitted(distributed_friction=True, gap_hold=True)
    relays = fitted(distributed_friction=True, gap_relays={"max_span_Nm": 20.0})
    grown = fitted(distributed_friction=True, gap_relays={"max_span_Nm": 20.0},
                   load_dependent_friction={"memory": True})
    steps = [SimpleNamespace(effect=e, before=b, after=a) for e, b, a in (
        ("distributed_friction", base, slip), ("gap_hold", slip, held), ("gap_relays", held, relays),
        ("friction_load_memory", relays, grown))]
    d = Diagnosis(base=base, final=grown, steps=steps, rejected=[], signatures=[], unexplained=False,
                  unexplained_description="", leftovers=[], notes=[], noise_arcsec=1.0)
    assert d.replaced() == {"gap_hold": "gap_relays"}
    assert d.final_added() == ["distributed_friction", "gap_relays", "friction_load_memory"]
    # a step that changes a switch already in (a memory for the level) replaces nothing
    level, memory = fitted(load_dependent_friction=True), fitted(load_dependent_friction={"memory": True})
    steps = [SimpleNamespace(effect="load_dependent_friction", before=base, after=level),
             SimpleNamespace(effect="friction_load_memory", before=level, after=memory)]
    d = Diagnosis(base=base, final=memory, steps=steps, rejected=[], signatures=[], unexplained=False,
                  unexplained_description="", leftovers=[], notes=[], noise_arcsec=1.0)
    assert d.replaced() == {} and d.final_added() == ["load_dependent_friction", "friction_load_memory"]
    doc = {"rmse_base": 2.0, "steps": [], "rejected": [], "rmse_final": 1.0, "noise_estimate": 1.0,
           "added": ["gap_relays"], "replaced": {"gap_hold": "gap_relays"}, "unexplained": False}
    assert "effects added: gap_relays; gap_hold replaced by gap_relays" in summary_text(doc)


def test_the_leftovers_say_whether_a_significant_signature_was_refitted(monkeypatch):
    """A significant signature beyond the refits a step tries was never refitted: its leftover
    says so, not that its extension failed to earn its keep."""
    from types import SimpleNamespace

    from torsionfit.diagnose import _loop
    from torsionfit.diagnose._signature import Evidence

    real_leftovers = _loop._leftovers  # the stand-in trail replaces it
    # nothing earns: the base model's step refits two of the three significant signatures
    catalog, calls, leftovers = _stand_in_trail(monkeypatch, {"drift": -30.0, "gap": -20.0, "creep": -10.0},
                                                lambda effects: 0.0)
    options = _loop.DiagnoseOptions(catalog=catalog, candidates_per_step=2, max_candidates_first_step=2)
    d = _loop.diagnose(SimpleNamespace(), options, seed=0)
    # ... and the trail's own evidence on the final model (here the base) goes with them
    assert d.steps == [] and leftovers == [({"drift", "gap"}, ["creep", "drift", "gap"])]
    # the wording of each: refitted; significant to the trail but not refitted; not significant to
    # the trail (its noise read otherwise), so never refitted
    monkeypatch.setattr(_loop, "_signatures", lambda ctx, options, added: [
        (e, Evidence(e.name, 40.0, 1, -9.0, 0.2, "a residual")) for e in catalog])
    trail = {"drift": Evidence("drift", 40.0, 1, -9.0, 0.2, ""), "gap": Evidence("gap", 40.0, 1, -9.0, 0.2, ""),
             "creep": Evidence("creep", 1.0, 1, -0.4, 0.01, "")}
    ctx = SimpleNamespace(hysteresis=[], te=[], runs=[])
    out = real_leftovers(ctx, options, set(), {"drift"}, trail)
    text = {ev.details["signature_of"]: (ev.details["refitted"], ev.description) for ev in out}
    assert text["drift"] == (True, "drift signature still significant (log10 p -9.0) but its extension did not "
                                   "earn its keep: a residual")
    assert text["gap"][0] is False and "its extension was not refitted on the final model" in text["gap"][1]
    assert "the trail's own test did not find it (log10 p -0.4" in text["creep"][1] and "never refitted" in text["creep"][1]
    # without the trail's evidence on the final model (the trail stopped at its limit of effects)
    out = real_leftovers(ctx, options, set(), set(), None)
    assert all("its extension was not refitted on the final model" in ev.description for ev in out)
