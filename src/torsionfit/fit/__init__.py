"""Fitting: parameters and priors, likelihood, MAP (optimistix) and its Laplace approximation."""

from ._denoise import denoise_torque as denoise_torque
from ._map import (
    MapResult as MapResult,
    best_start as best_start,
    fit_map as fit_map,
    iid_noise as iid_noise,
    laplace_covariance as laplace_covariance,
    laplace_from_parts as laplace_from_parts,
    log_density as log_density,
    map_starts as map_starts,
    rival_note as rival_note,
    rival_optima as rival_optima,
)
from ._prior import build_priors as build_priors, first_look_stiffness as first_look_stiffness
from ._problem import (
    FitProblem as FitProblem,
    NoiseOptions as NoiseOptions,
    build_problem as build_problem,
    check_fittable as check_fittable,
    model_inputs as model_inputs,
    temperatures_resolving_friction as temperatures_resolving_friction,
)
