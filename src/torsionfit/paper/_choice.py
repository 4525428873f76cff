"""The posterior behind the paper's numbers: the sampled one when the sampler converged within
its budget, else the Laplace approximation at the same MAP — with which one and why recorded in
the fit's diagnostics (``posterior``, ``posterior_reason``, ``sampled_attempt``), so that
``tables.json`` and the page say it."""

import dataclasses
import warnings

from ..report import campaign_model, finish_fit, fit_campaign
from ..sample import ConvergenceWarning

#: what a fallback keeps of the sampler's own diagnostics (the run that was not used)
ATTEMPT_KEYS = ("sampler", "sampler_choice_reason", "converged", "rhat_max", "ess_min", "ess_tail_min",
                "n_divergent", "n_steps", "n_draws", "n_chains", "tau_max", "reason")


def _marked(fit, posterior: str, reason: str, attempt: dict | None = None):
    extra = {"posterior": posterior, "posterior_reason": reason}
    if attempt is not None:
        extra["sampled_attempt"] = attempt
    return dataclasses.replace(fit, diagnostics={**fit.diagnostics, **extra})


def fit_with_fallback(campaign, options, seed: int):
    """``fit_campaign(campaign, options, seed)``; when ``options.sampler`` samples (emcee, nuts,
    auto) and the sampler does not converge within its budget, the Laplace approximation of
    the same MAP instead (``finish_fit`` with ``sampler="laplace"``). The fit's diagnostics
    say which (``posterior``: "sampled" or "laplace") and why (``posterior_reason``)."""
    if options.sampler == "laplace":
        return _marked(fit_campaign(campaign, options, seed), "laplace", "asked for (sampler laplace)")
    with warnings.catch_warnings():
        # an unconverged sampler is not a failure here: its reason is kept and Laplace used
        warnings.simplefilter("ignore", ConvergenceWarning)
        fit = fit_campaign(campaign, options, seed)
    d = fit.diagnostics
    if d["converged"]:
        return _marked(fit, "sampled", f"{d['sampler']} converged within its budget ({_budget(options)})")
    laplace_options = dataclasses.replace(options, sampler="laplace")
    laplace = finish_fit(fit.campaign, laplace_options, campaign_model(fit.campaign, options), fit.problem,
                         fit.map_result, seed)
    attempt = {k: d[k] for k in ATTEMPT_KEYS if k in d}
    why = f"{d['sampler']} did not converge within its budget ({_budget(options)}): {d.get('reason') or 'see sampled_attempt'}"
    return _marked(laplace, "laplace", why, attempt)


def _budget(options) -> str:
    emcee = f"emcee ≤ {options.max_steps} steps"
    nuts = f"NUTS {options.n_chains} chains × ({options.n_warmup} warm-up + ≤ {options.max_draws} draws)"
    return {"emcee": emcee, "nuts": nuts}.get(options.sampler, f"{emcee}, then {nuts}")


def posterior_line(fits: dict) -> str:
    """One line: the posterior each fit (name → ``fit.json``-style entry with diagnostics) used."""
    parts = []
    for name, f in fits.items():
        d = f["diagnostics"]
        if d.get("posterior") == "sampled":
            parts.append(f"{name} sampled ({d['sampler']}, R̂ max {d['rhat_max']:.3f}, ESS min {d['ess_min']:.0f})")
        elif "sampled_attempt" in d:
            parts.append(f"{name} Laplace ({d['sampled_attempt']['sampler']} not converged within its budget)")
        else:
            parts.append(f"{name} Laplace")
    return "posteriors: " + "; ".join(parts)
