"""How ``torsionfit paper`` fits and samples: the full settings (every run, four MAP starts, the
posterior sampled within a budget, the Laplace approximation where the sampler does not
converge in it) and the quick ones (the slowest loop and the TE runs, decimated, one start, the
Laplace approximation) for tests and screening. Every number here is written to ``tables.json``
with the results.

Why a budget and a fallback: a sampled posterior is the better answer only when it converged
(R̂, ESS, no divergence; ``report.FitOptions``); a fit whose sampler did not converge within
``max_steps`` (emcee) or ``max_draws`` (NUTS) falls back to the Laplace approximation at the same
MAP, and ``tables.json`` says which posterior each fit used and why (``_choice.py``)."""

import dataclasses
from dataclasses import dataclass, field

from ..report import FitOptions


@dataclass(frozen=True)
class PaperSettings:
    """``sampler``: "laplace", or "emcee", "nuts", "auto" (as for ``torsionfit fit``) within the
    budget ``max_steps`` (emcee) and ``n_chains`` × ``n_warmup`` + ``max_draws`` (NUTS), the
    Laplace approximation where that sampler does not converge; ``all_loops``: fit every
    hysteresis run (else only the slowest loop, with all TE runs); ``decimate``: block-mean
    factor per campaign name;
    ``grid_torques`` × ``grid_speeds``: the operating grid (speeds 1..``grid_max_speed_rpm``);
    ``band_draws``: posterior draws behind a figure's band; ``seed``: every random choice."""

    quick: bool
    seed: int = 0
    sampler: str = "emcee"
    n_starts: int = 4
    max_steps: int = 20_000
    n_chains: int = 4
    n_warmup: int = 1000
    max_draws: int = 2000
    laplace_draws: int = 4000
    metric_draws: int = 2000
    all_loops: bool = True
    decimate: dict = field(default_factory=dict)
    grid_torques: int = 9
    grid_speeds: int = 6
    grid_max_speed_rpm: float = 10.0
    band_draws: int = 400

    def fit_options(self, effects: dict, campaign_name: str, progress: bool = False) -> FitOptions:
        """The fit of one bundled campaign with the model ``effects`` (``progress``: the sampler's bar)."""
        return FitOptions(effects=dict(effects), sampler=self.sampler, n_starts=self.n_starts,
                          max_steps=self.max_steps, n_chains=self.n_chains, n_warmup=self.n_warmup,
                          max_draws=self.max_draws, laplace_draws=self.laplace_draws,
                          metric_draws=self.metric_draws, progress=progress,
                          decimate=int(self.decimate.get(campaign_name, 1)))

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


#: the published reproduction: every run, four starts, the posterior sampled as ``torsionfit fit``
#: does (auto: emcee, or NUTS where emcee's checks say it needs more than its budget) within
#: 10 000 emcee steps and 4 × (1000 + ≤ 1000) NUTS draws, the Laplace approximation where that
#: does not converge (TE runs keep ≥ 180 samples per revolution after decimation, enough for the
#: large reducer's order-39 kinematic error)
FULL = PaperSettings(quick=False, sampler="auto", max_steps=10_000, max_draws=1000,
                     decimate={"paper-small": 2, "paper-large": 4})
#: tests and screening: MAP + Laplace, one start, the slowest loop and the TE runs (decimated),
#: a 5 × 4 grid
QUICK = PaperSettings(quick=True, sampler="laplace", n_starts=1, laplace_draws=1000, metric_draws=300,
                      all_loops=False, decimate={"paper-small": 5, "paper-large": 4}, grid_torques=5,
                      grid_speeds=4, band_draws=150)


def paper_settings(quick: bool, seed: int, sampler: str | None = None) -> PaperSettings:
    """:data:`QUICK` or :data:`FULL` with ``seed`` (and ``sampler`` — "laplace", "emcee", "nuts" or
    "auto" — if given)."""
    settings = dataclasses.replace(QUICK if quick else FULL, seed=int(seed))
    return settings if sampler is None else dataclasses.replace(settings, sampler=sampler)
