"""Plain NumPy reference of the hysteresis forward model: base model + creep (DESIGN §1.1).

The same physics as ``CampaignModel(run_kinds=("hysteresis",), creep=Creep())`` — linear
compliance, Dahl friction, smooth backlash, creep element, one angle offset — written the way
one would without JAX: the element-wise parts are vectorised NumPy, the two affine recurrences
(friction state z, creep twist θ_c) are explicit loops over the samples.

- One parameter set (every value a scalar; ``angle_offset`` may be a length-1 array): the
  recurrences run over Python floats, the fastest plain-Python loop (NumPy scalar ops are
  slower than float arithmetic).
- A batch of walkers (every value with a leading walker axis W): the loop runs over samples and
  each step updates all W walkers at once with in-place NumPy operations.

``tests/test_benchmark_reference.py`` checks this equals the JAX model to 1e-10 rad, so the
benchmark compares like with like.
"""

import numpy as np

COMPONENTS = ("elastic", "friction", "geometric", "creep", "offset")


def affine_recurrence(a, b, x0):
    """x[n] = a[n]·x[n−1] + b[n] for n = 1..N, returned as x[1..N].

    ``a``, ``b`` of shape (N,) with a scalar ``x0`` (Python-float loop), or of shape (N, W)
    with ``x0`` of shape (W,) (loop over samples, NumPy across walkers).
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if a.ndim == 1:
        out = [0.0] * len(a)
        x = float(x0)
        for n, (an, bn) in enumerate(zip(a.tolist(), b.tolist())):
            x = an * x + bn
            out[n] = x
        return np.array(out)
    out = np.empty_like(a)
    x = np.array(np.broadcast_to(x0, a.shape[1:]), float)
    for n in range(a.shape[0]):
        np.multiply(a[n], x, out=x)
        x += b[n]
        out[n] = x
    return out


def components(params, time_s, torque_Nm):
    """Components (rad) of one hysteresis run, plus ``total``, ``mesh_torque``, ``friction_state``.

    ``params``: the JAX model's dict (``stiffness``, ``friction_torque``, ``dahl_torque``,
    ``gap``, ``gap_torque``, ``creep_stiffness``, ``creep_time``, ``angle_offset``). With scalar
    values the arrays returned have shape (N,); with a leading walker axis W on every value
    (``angle_offset`` of shape (W,) or (W, 1)) they have shape (W, N).
    """
    t = np.asarray(time_s, float)
    tau = np.asarray(torque_Nm, float)
    k = np.asarray(params["stiffness"], float)
    batched = k.ndim == 1
    if batched:  # work in (N, W): the loop runs over rows, contiguous walkers per row

        def p(name):
            return np.asarray(params[name], float).reshape(-1)[None, :]

        tau_c = tau[:, None]
        dt = np.diff(t)[:, None]
        offset = np.asarray(params["angle_offset"], float).reshape(len(k), -1)[:, 0][None, :]
        z0 = np.zeros(len(k))
    else:

        def p(name):
            return float(np.asarray(params[name], float))

        tau_c = tau
        dt = np.diff(t)
        offset = float(np.asarray(params["angle_offset"], float).reshape(-1)[0])
        z0 = 0.0

    stiffness, t_f, tau_d = p("stiffness"), p("friction_torque"), p("dahl_torque")
    gap, gap_torque = p("gap"), p("gap_torque")
    k_c, t_c = p("creep_stiffness"), p("creep_time")

    # Dahl friction: z ← a z + b, a = exp(−|Δτ|/τ_d), b = sgn(Δτ)(1 − a); z starts at rest (0)
    d_tau = np.diff(tau_c, axis=0)
    a = np.exp(-np.abs(d_tau) / tau_d)
    b = np.sign(d_tau) * (1.0 - a)
    z_rest = np.zeros_like(a[:1]) + z0
    z = np.concatenate([z_rest, affine_recurrence(a, b, z0)], axis=0)
    friction_torque = t_f * z
    mesh = tau_c - friction_torque

    def spring_and_gap(x):
        return x / stiffness + 0.5 * gap * np.tanh(x / gap_torque)

    elastic = tau_c / stiffness
    geometric = 0.5 * gap * np.tanh(tau_c / gap_torque)
    friction = spring_and_gap(mesh) - elastic - geometric

    # creep: θ_c ← e θ_c + (1 − e) τ_m[n−1]/K_c, e = exp(−Δt/T_c); starts in equilibrium
    target = mesh / k_c
    e = np.exp(-dt / t_c)
    creep = np.concatenate([target[:1], affine_recurrence(e, (1.0 - e) * target[:-1], target[0])], axis=0)
    offset = np.zeros_like(tau_c) + offset

    parts = dict(elastic=elastic, friction=friction, geometric=geometric, creep=creep, offset=offset)
    total = 0
    for name in ("elastic", "friction", "geometric", "creep"):
        total = total + parts[name]
    total = total + 0.0 + 0.0 + offset  # kinematic and drift are zero here, as in the JAX model
    out = {**parts, "total": total, "mesh_torque": mesh, "friction_state": z}
    if batched:
        out = {key: np.ascontiguousarray(val.T) for key, val in out.items()}
    return out


def predict(params, time_s, torque_Nm):
    """Predicted output twist (rad): shape (N,) for one parameter set, (W, N) for a batch."""
    return components(params, time_s, torque_Nm)["total"]
