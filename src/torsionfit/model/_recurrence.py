"""Scanned recurrences: affine ones x[n] = a[n]·x[n−1] + b[n], the exact one-sample update
shared by the Dahl friction state, the creep element and first-order lags, and max-plus ones
x[n] = max(a[n], x[n−1] + b[n]), a peak held and let down by a set amount per sample.

Either map composes associatively, so the whole sequence can be evaluated by
`jax.lax.associative_scan` in O(log N) depth (a win on accelerators and for one long
sequence) or by a serial `lax.scan` (faster on a small CPU with many walkers vmapped).
``method="auto"`` picks per backend; `benchmarks/bench_hysteresis_scan.py` measures both.
"""

from typing import Literal

import jax
import jax.numpy as jnp

ScanMethod = Literal["auto", "associative", "serial"]


def _compose(earlier, later):
    a1, b1 = earlier
    a2, b2 = later
    return a2 * a1, a2 * b1 + b2


def resolve_scan_method(method: ScanMethod) -> Literal["associative", "serial"]:
    """``auto`` → serial on CPU (measured faster with vmapped walkers), associative elsewhere."""
    if method == "auto":
        return "serial" if jax.default_backend() == "cpu" else "associative"
    if method not in ("associative", "serial"):
        raise ValueError(f"scan method must be 'auto', 'associative' or 'serial', not {method!r}")
    return method


def affine_scan(a, b, x0, method: ScanMethod = "auto"):
    """Return x[1..N] for x[n] = a[n]·x[n−1] + b[n] (arrays ``a``, ``b`` of length N)."""
    method = resolve_scan_method(method)
    a = jnp.asarray(a)
    b = jnp.asarray(b)
    if method == "associative":
        big_a, big_b = jax.lax.associative_scan(_compose, (a, b))
        return big_a * x0 + big_b

    def step(x, ab):
        x_new = ab[0] * x + ab[1]
        return x_new, x_new

    _, xs = jax.lax.scan(step, jnp.asarray(x0, dtype=b.dtype), (a, b))
    return xs


def first_order_lag(time_s, x, lag_s, method: ScanMethod = "auto"):
    """``x`` through a first-order lag ``T·dy/dt = x − y`` (``T = lag_s``), starting at rest
    at the first sample; exact for an input linear between samples (first-order hold):

    ``y[n] = e·y[n−1] + x[n] − e·x[n−1] − g·(x[n] − x[n−1])``,
    ``e = exp(−Δt/T)``, ``g = (1 − e)·T/Δt`` (1 at Δt = 0, where y holds).

    ``T → 0`` is the identity, with first-order effect ``−T·dx/dt``.
    """
    x = jnp.asarray(x)
    dt = jnp.diff(jnp.asarray(time_s, dtype=x.dtype))
    ratio = dt / lag_s
    e = jnp.exp(-ratio)
    # (1 − e)/ratio, well conditioned for ratio → 0 (duplicate stamps) and ratio → ∞ (T → 0)
    safe = jnp.where(ratio > 0, ratio, 1.0)
    g = jnp.where(ratio > 0, -jnp.expm1(-safe) / safe, 1.0)
    b = x[1:] - e * x[:-1] - g * (x[1:] - x[:-1])
    return jnp.concatenate([x[:1], affine_scan(e, b, x[0], method)])


def _compose_max_plus(earlier, later):
    a1, b1 = earlier
    a2, b2 = later
    return jnp.maximum(a2, a1 + b2), b1 + b2


def max_plus_scan(a, b, x0, method: ScanMethod = "auto"):
    """Return x[1..N] for x[n] = max(a[n], x[n−1] + b[n]) (arrays ``a``, ``b`` of length N)."""
    method = resolve_scan_method(method)
    a = jnp.asarray(a)
    b = jnp.asarray(b)
    if method == "associative":
        big_a, big_b = jax.lax.associative_scan(_compose_max_plus, (a, b))
        return jnp.maximum(big_a, x0 + big_b)

    def step(x, ab):
        x_new = jnp.maximum(ab[0], x + ab[1])
        return x_new, x_new

    _, xs = jax.lax.scan(step, jnp.asarray(x0, dtype=b.dtype), (a, b))
    return xs
