"""Runs whose angle noise lies below the encoder step.

The likelihood counts the encoder's quantisation as independent noise of sd step/√12 (the
floor under every run's noise). That holds where the angle moves many steps between samples
and the rounding falls anew each time. Where the noise above the floor is smaller than the
floor itself, the rounding is most of the angle's error, and it is not random: a loop measured
again repeats it sample for sample, and a parameter read off a few samples (the gap's closing
torque across a crossing sampled a few times) takes its pattern as a bias the interval does not
hold. On the SYNTHETIC statistics bench with 1″ steps and no other angle noise ``gap_torque``
came out 2.5 % high in every one of 20 campaigns at an sd of 1 % (tests/test_fit_statistics.py).
"""

import numpy as np

from ..units import ANGLE_UNITS

ARCSEC_PER_RAD = 1.0 / ANGLE_UNITS["arcsec"]


def runs_below_the_encoder_step(problem, u, run_names) -> dict[str, dict[str, float]]:
    """Hysteresis runs (by name) whose fitted noise above the floor at ``u`` (its marginal sd:
    s_r/√(1 − ρ_r²) with AR(1) noise) is below the encoder's quantisation sd (the floor,
    step/√12): run → {"noise_arcsec", "floor_arcsec"}."""
    floors = np.asarray(problem.floors, float)
    u = np.asarray(u, float)
    _, rho = problem.noise_values(u)
    s = np.exp(u[problem.n_nonlinear:problem.n_nonlinear + problem.n_runs]) / np.sqrt(1.0 - np.asarray(rho, float) ** 2)
    out = {}
    for r, name in enumerate(run_names):
        if problem.model.run_kinds[r] == "hysteresis" and floors[r] > 0 and s[r] < floors[r]:
            out[name] = {"noise_arcsec": float(s[r] * ARCSEC_PER_RAD), "floor_arcsec": float(floors[r] * ARCSEC_PER_RAD)}
    return out


def quantisation_note(below: dict) -> str:
    """One line on the runs of :func:`runs_below_the_encoder_step`; empty when there are none."""
    if not below:
        return ""
    runs = ", ".join(f"{k} ({v['noise_arcsec']:.2g}″ against {v['floor_arcsec']:.2g}″)" for k, v in below.items())
    return (f"angle noise below the encoder step on {runs}: the rounding is most of the angle's error and is "
            "counted as independent noise; it repeats with the loop, and a parameter read off a few samples "
            "(the gap's closing torque across a fast crossing) can be biased beyond its interval — sample "
            "faster across the crossing or use a finer encoder")
