"""What a batch does to every unit: fit options, the spec (if any), which units get the full
posterior, figures, group size and the seed."""

import hashlib
from dataclasses import dataclass, field, replace

from ..accept import Spec
from ..report import FitOptions

LAPLACE, EMCEE = "laplace", "emcee"


@dataclass(frozen=True)
class BatchOptions:
    """``fit.sampler`` is every unit's sampler; the units named in ``posterior_units`` get the
    emcee posterior whatever it is. ``seed`` is every unit's seed (as ``torsionfit fit --seed``
    on that unit alone). ``group_size``: units of one shape fitted together, at most."""

    fit: FitOptions = field(default_factory=lambda: FitOptions(sampler=LAPLACE, progress=False))
    spec: Spec | None = None
    spec_digest: str | None = None  # sha256 of the spec file: a changed spec redoes the units
    posterior_units: frozenset = frozenset()
    figures: bool = False
    group_size: int = 16

    def __post_init__(self):
        # the batch's MAP solves many units at once and has no refit for class shares: without
        # this check every unit would silently keep one noise level
        if self.fit.noise.cycle_class_noise:
            raise ValueError("BatchOptions: NoiseOptions.cycle_class_noise is not supported by the batch "
                             "(fit such units one at a time: torsionfit fit --class-noise)")
        if self.fit.noise.first_excursion_conditioning:
            raise ValueError("BatchOptions: NoiseOptions.first_excursion_conditioning is not supported by the batch "
                             "(fit such units one at a time: torsionfit fit --condition-first-excursions)")
    seed: int = 0
    command: str | None = None  # the command line, recorded in the outputs (not a setting: a re-run keeps units)

    def sampler_of(self, unit: str) -> str:
        return EMCEE if unit in self.posterior_units else self.fit.sampler

    def fit_options_of(self, unit: str) -> FitOptions:
        return replace(self.fit, sampler=self.sampler_of(unit))

    def settings_of(self, unit: str) -> dict:
        """What a unit's stored result depends on (compared on a re-run)."""
        f = self.fit
        return {"seed": self.seed, "sampler": self.sampler_of(unit), "spec_sha256": self.spec_digest,
                "effects": repr(sorted(f.effects.items())), "decimate": f.decimate, "max_steps": f.max_steps,
                "noise": repr(f.noise), "n_starts": f.n_starts, "laplace_draws": f.laplace_draws,
                "metric_draws": f.metric_draws, "lost_motion_pct": f.lost_motion_pct, "figures": self.figures}


def posterior_sample(units: list[str], k: int, seed: int) -> frozenset:
    """``k`` of ``units`` for the full posterior, chosen by ``seed``: the k smallest
    sha256(seed:unit) — the same units whatever their order or the executor."""
    if k < 0:
        raise ValueError(f"posterior sample size must be ≥ 0, got {k}")
    score = {u: hashlib.sha256(f"{seed}:{u}".encode()).hexdigest() for u in units}
    return frozenset(sorted(units, key=score.__getitem__)[:k])
