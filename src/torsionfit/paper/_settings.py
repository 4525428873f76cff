"""How ``torsionfit paper`` fits and samples: the full settings (every run, four MAP starts, the
Laplace approximation; emcee on request) and the quick ones (the slowest loop and the TE runs,
decimated, one start) for tests and screening. Every number here is written to ``tables.json``
with the results.

Why Laplace by default: emcee on the bundled small campaign had not converged after 20 000 steps
(20 min on the shared 2-core machine; R̂ max 1.03): the slowest parameter, the noise above the
encoder floor of one loop (τ ≈ 815 steps), sits in a funnel — the synthetic angles are quantised truth, so the
noise is at the floor and its scale is not identified. (Measured with the earlier moves,
DE 0.8 + stretch 0.2; with the Laplace move a 6000-step run still had τ_max ≈ 850, for a speed
term of the compliance: see the README.) ``--sampler emcee`` runs it anyway and
reports ``converged: false`` when it is not."""

import dataclasses
from dataclasses import dataclass, field

from ..report import FitOptions


@dataclass(frozen=True)
class PaperSettings:
    """``sampler``: "emcee" or "laplace"; ``all_loops``: fit every hysteresis run (else only the
    slowest loop, with all TE runs); ``decimate``: block-mean factor per campaign name;
    ``grid_torques`` × ``grid_speeds``: the operating grid (speeds 1..``grid_max_speed_rpm``);
    ``band_draws``: posterior draws behind a figure's band; ``seed``: every random choice."""

    quick: bool
    seed: int = 0
    sampler: str = "emcee"
    n_starts: int = 4
    max_steps: int = 20_000
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
                          max_steps=self.max_steps, laplace_draws=self.laplace_draws,
                          metric_draws=self.metric_draws, progress=progress,
                          decimate=int(self.decimate.get(campaign_name, 1)))

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


#: the published reproduction: every run, four starts, the Laplace approximation (TE runs keep
#: ≥ 180 samples per revolution after decimation, enough for the large reducer's order-39
#: kinematic error)
FULL = PaperSettings(quick=False, sampler="laplace", decimate={"paper-small": 2, "paper-large": 4})
#: tests and screening: MAP + Laplace, one start, the slowest loop and the TE runs (decimated),
#: a 5 × 4 grid
QUICK = PaperSettings(quick=True, sampler="laplace", n_starts=1, laplace_draws=1000, metric_draws=300,
                      all_loops=False, decimate={"paper-small": 5, "paper-large": 4}, grid_torques=5,
                      grid_speeds=4, band_draws=150)


def paper_settings(quick: bool, seed: int, sampler: str | None = None) -> PaperSettings:
    """:data:`QUICK` or :data:`FULL` with ``seed`` (and ``sampler``, "laplace" or "emcee", if given)."""
    settings = dataclasses.replace(QUICK if quick else FULL, seed=int(seed))
    return settings if sampler is None else dataclasses.replace(settings, sampler=sampler)
