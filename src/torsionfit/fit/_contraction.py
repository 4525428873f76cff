"""Which model parameters do the data inform, and which keep their prior?

Every model parameter has a normal prior in the unconstrained space (fit/_prior.py). A
parameter the data inform comes out of the fit with a posterior far narrower than that prior;
one they do not keeps the prior's width, and its value — and every metric read off it — is the
prior's, however the sampler converged. TE runs whose zeros absorb the twist leave the
stiffness at 1.0× its prior's sd, and TE runs alone (which never reverse) leave the friction's
pre-sliding torque τ_d at 1.0×. A fit lists them in fit.json (``diagnostics.prior_dominated``)
and names the reducer's scalar parameters among them in one line.
"""

import numpy as np

#: a parameter whose posterior sd is at least this share of its prior's is the prior's: the data
#: cut its variance by less than half
PRIOR_DOMINATED_SD_RATIO = 0.7
#: parameters that are no property of the reducer (the state before a run's first sample): listed
#: in fit.json, not named in the fit's note
_NUISANCE_SUFFIX = "_start"


def prior_dominated(problem, draws_u) -> dict[str, float]:
    """Model parameter (name, element-wise) → posterior sd over prior sd, in the unconstrained
    space, for those at or above :data:`PRIOR_DOMINATED_SD_RATIO` (the latent torque lines,
    which carry their own smoothing prior, are left out)."""
    draws = np.asarray(draws_u, float)
    if draws.ndim != 2 or draws.shape[0] < 2:
        return {}
    prior_sd = np.asarray(problem.prior_sd, float)
    ratio = draws[:, :prior_sd.size].std(axis=0) / prior_sd
    out, i = {}, 0
    for p in problem.physics:
        names = [p.name] if p.size == 1 else [f"{p.name}[{k}]" for k in range(p.size)]
        for name, r in zip(names, ratio[i:i + p.size]):
            if r >= PRIOR_DOMINATED_SD_RATIO:
                out[name] = round(float(r), 3)
        i += p.size
    return out


def prior_dominated_named(found: dict[str, float], problem) -> list[str]:
    """The reducer's scalar parameters among ``found`` (:func:`prior_dominated`). The elements of
    a vector parameter describe a shape (a gap's relay shares, slip elements), and the data pin
    the whole, not every element (on a measured loop the gap is sharp at 0.03× its prior's sd
    while most of its 27 relay shares keep their prior): they are listed in fit.json, not named;
    nor is the state before a run's first sample."""
    scalar = {p.name for p in problem.physics if p.size == 1}
    return [n for n in found if n in scalar and not n.endswith(_NUISANCE_SUFFIX)]


def prior_dominated_note(found: dict[str, float], problem) -> str | None:
    """One line naming the parameters of :func:`prior_dominated_named`, None when none."""
    described = {p.name: p.description for p in problem.physics}
    named = prior_dominated_named(found, problem)
    if not named:
        return None
    parts = ", ".join(f"{n} ({described[n]}: posterior sd {found[n]:.2f}× the prior's)" for n in named)
    return f"the data barely inform {parts}: their values, and the metrics that read them, are the prior's"
