"""Play (backlash) operators: x[n] = clamp(x[n−1], lo[n], hi[n]), the exact state update of a
Maxwell-slip / Prandtl–Ishlinskii element.

An element sticks (its state stays) while the input keeps it inside the band [lo, hi] and is
dragged along by the band's edge once the input pushes past it. Clamp maps compose into clamp
maps — clamp(clamp(x, l1, h1), l2, h2) = clamp(x, clamp(l1, l2, h2), clamp(h1, l2, h2)) — so
the sequence evaluates by `jax.lax.associative_scan` in O(log N) depth as well as by a serial
`lax.scan` (faster on a small CPU, like the affine recurrences in ``_recurrence``).
"""

import jax
import jax.numpy as jnp

from ._recurrence import ScanMethod, resolve_scan_method


def _compose(earlier, later):
    lo1, hi1 = earlier
    lo2, hi2 = later
    return jnp.clip(lo1, lo2, hi2), jnp.clip(hi1, lo2, hi2)


def play_scan(lo, hi, x0, method: ScanMethod = "auto"):
    """Return x[1..N] for x[n] = clamp(x[n−1], lo[n], hi[n]); ``lo ≤ hi`` of shape (N, ...),
    ``x0`` broadcastable to one row."""
    method = resolve_scan_method(method)
    lo = jnp.asarray(lo)
    hi = jnp.asarray(hi)
    x0 = jnp.broadcast_to(jnp.asarray(x0, dtype=lo.dtype), lo.shape[1:])
    if method == "associative":
        big_lo, big_hi = jax.lax.associative_scan(_compose, (lo, hi))
        return jnp.clip(x0, big_lo, big_hi)

    def step(x, band):
        x_new = jnp.clip(x, band[0], band[1])
        return x_new, x_new

    _, xs = jax.lax.scan(step, x0, (lo, hi))
    return xs
