"""Slow drift of each run over its own time (thermal drift, DESIGN §3 ``thermal_drift``).

Two shapes, both linear in their coefficients (solved by variable projection, no priors):

- ``linear``: d_r · t, t from the run's first sample (rad/s per run);
- ``warm_up``: the linear term plus saturating exponentials Σ_j a_rj (1 − e^(−t/τ_j)) at
  fixed time constants τ_j = f_j · (the run's duration), f_j in ``WARM_UP_FRACTIONS``. A
  warm-up a·(1 − e^(−t/T)) of any T from a few per cent of the run to far beyond it (where it
  is linear) is within a few per cent of its amplitude of this basis, without a non-linear
  time constant to fit.
"""

import jax.numpy as jnp

from ._parameter import Parameter

#: time constants of the warm-up basis, as fractions of each run's duration
WARM_UP_FRACTIONS = (1.0 / 32.0, 1.0 / 8.0, 1.0 / 2.0)

SHAPES = ("linear", "warm_up")


def drift_parameters(n_runs: int, shape: str) -> tuple[Parameter, ...]:
    out = (Parameter("drift", "real", "rad/s", "linear drift per run", n_runs, True),)
    if shape == "warm_up":
        out += (Parameter("drift_warmup", "real", "rad",
                          f"warm-up amplitudes per run at time constants {WARM_UP_FRACTIONS} of the run's duration "
                          "(run-major)", n_runs * len(WARM_UP_FRACTIONS), True),)
    return out


def run_drift(params, run_index: int, time_s, shape: str):
    """Drift (rad) of run ``run_index`` over its sample times."""
    t = time_s - time_s[0]
    out = jnp.atleast_1d(params["drift"])[run_index] * t
    if shape == "warm_up":
        span = jnp.maximum(t[-1], 1e-12)
        k = len(WARM_UP_FRACTIONS)
        amps = jnp.atleast_1d(params["drift_warmup"])[run_index * k:(run_index + 1) * k]
        taus = span * jnp.asarray(WARM_UP_FRACTIONS)
        out = out + (1.0 - jnp.exp(-t[:, None] / taus[None, :])) @ amps
    return out
