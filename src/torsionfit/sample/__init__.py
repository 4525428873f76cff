"""Posterior sampling (emcee, NUTS, tempered SMC, Laplace draws) and the ArviZ tree of a fit (DESIGN §2, §5.2)."""

from ._emcee import (
    BufferedHDFBackend as BufferedHDFBackend,
    ConvergenceWarning as ConvergenceWarning,
    SampleResult as SampleResult,
    default_n_walkers as default_n_walkers,
    run_sampler as run_sampler,
)
from ._convergence import chain_diagnostics as chain_diagnostics
from ._nuts import (
    Coordinates as Coordinates,
    NutsResult as NutsResult,
    run_nuts as run_nuts,
)
from ._laplace import LaplaceResult as LaplaceResult, laplace_result as laplace_result
from ._mixture import SplitNormalMixture as SplitNormalMixture, evidence_log_weights as evidence_log_weights
from ._pareto import good_k as good_k, importance_pareto_k as importance_pareto_k
from ._smc import SMCResult as SMCResult, tempered_smc as tempered_smc
from ._split_normal import SplitNormal as SplitNormal, split_normal as split_normal
from ._tree import (
    convergence_summary as convergence_summary,
    draw_thinning as draw_thinning,
    load_tree as load_tree,
    pointwise_draw_limit as pointwise_draw_limit,
    psis_loo as psis_loo,
    save_tree as save_tree,
    to_datatree as to_datatree,
)
