"""A noise level per cycle class: the torque cycles of a hysteresis run grouped by amplitude,
each group with its own noise level, the levels read from the residuals at the MAP.

A bench file runs cycles of very different amplitude — ±4 N·m play ramps before ±40 N·m
stiffness ramps. What the model misses is not the same on both: on measured cycloidal loops
the play ramps' misfit is 2–4× the large ramps' where the gap crossing is a fast jump the model
crosses late (baseline units), and smaller than theirs where the loop is narrow (preloaded
units). One noise level for the whole file weighs each class by the other's misfit, and a
predictive interval for a new large ramp gets the play ramps' width. A level proportional to
the amplitude (:func:`~torsionfit.fit._problem.cycle_amplitude_shape`) fixes the ratio in
advance (1 : 10 for those files) and the fit then chases the play ramps; here the ratio is the
data's.

The ratios are plug-in estimates (feasible generalised least squares): fit with one level,
read each class's mean squared residual, refit with the levels in that ratio, repeat. The run's
noise parameter stays the level of its largest cycles, so everything that reads it — the
sampler, the predictive of a large ramp — is unchanged in meaning; with thousands of samples per
class the ratios' own uncertainty is negligible beside the physics'.

**First excursions** (``NoiseOptions.first_excursion_class``). The ramps that first load a run
beyond every earlier peak of their sign can be a class of their own among the largest cycles.
On measured printed cycloidal loops the first ±40 N·m ramp after the play ramps does not repeat:
its first branches differ from the next ramp's by several times what the later ramps differ by
from each other (the loop shakes down; ``scripts/measured_ramp_repeats.py``), and a fit that
weighs it as a repeat bends the model of every later ramp towards it. With a level of its own,
read from its residuals like the other classes', the fit weighs it by how well the model draws
it; class 0, whose level predicts a new large ramp, is then the repeats'.

**Conditioning** (``NoiseOptions.first_excursion_conditioning``): the same first excursions out
of the likelihood altogether — they drive the model's state (friction, gap) and weigh nothing,
the limit of their class's level going to infinity; a test procedure's preconditioning cycles,
run before it records. A run without repeats of its largest cycles keeps them.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .. import model as m
from .._segments import monotone_segments

#: consecutive ramp amplitudes (sorted) more than this factor apart start a new class
CLASS_AMPLITUDE_RATIO = 2.0
#: a class needs this many samples for a level of its own (else it joins the nearer class)
CLASS_MIN_SAMPLES = 50
#: the range a class's level may take, as a share of the largest cycles' level
CLASS_SHARE_RANGE = (0.05, 20.0)
#: a ramp is a first excursion when it ends beyond every earlier peak of its sign by more than this
#: share of that peak (a repeat of the same command ends within the torque's noise of it)
FIRST_EXCURSION_MARGIN = 0.1
#: rounds of (levels from the residuals, refit): on the friction test bench the second moved the
#: shares by 1–3 %, a third by less than 0.1 %
CLASS_ITERATIONS = 2


def ramp_amplitudes(torque_Nm) -> np.ndarray:
    """Per sample: the peak |torque| (N·m) of the monotone ramp it lies on (a turning sample
    takes the larger of its two ramps)."""
    tau = np.asarray(torque_Nm, float)
    smooth, segments = monotone_segments(tau, reversal_fraction=0.05)
    amp = np.zeros(tau.size)
    for a, b, _ in segments:
        amp[a:b + 1] = np.maximum(amp[a:b + 1], max(abs(smooth[a]), abs(smooth[b])))
    return amp


def amplitude_classes(torque_Nm, ratio: float = CLASS_AMPLITUDE_RATIO,
                      min_samples: int = CLASS_MIN_SAMPLES) -> np.ndarray:
    """Per sample: the index of its cycle class, 0 for the largest cycles, 1 for the next
    smaller, …; a class starts where the sorted ramp amplitudes jump by more than ``ratio``."""
    amp = ramp_amplitudes(torque_Nm)
    if amp.size == 0 or not np.max(amp) > 0:
        return np.zeros(amp.size, dtype=int)
    levels = np.unique(np.maximum(amp, 1e-12 * np.max(amp)))[::-1]  # largest first
    edges = [levels[0]]  # the top amplitude of each class
    for hi, lo in zip(levels[:-1], levels[1:]):
        if hi / lo > ratio:
            edges.append(lo)
    # class k: amplitudes in (edges[k+1], edges[k]], i.e. the count of lower tops at or above it
    classes = np.sum(np.asarray(edges[1:])[None, :] >= amp[:, None], axis=1)
    # a class too small for its own level joins its larger neighbour (the next smaller, for class 0)
    for k in range(len(edges) - 1, -1, -1):
        if 0 < np.sum(classes == k) < min_samples and len(np.unique(classes)) > 1:
            classes[classes == k] = k - 1 if k > 0 else 1
    _, classes = np.unique(classes, return_inverse=True)
    return classes.astype(int)


def first_excursions(torque_Nm, margin: float = FIRST_EXCURSION_MARGIN) -> np.ndarray:
    """Per sample: True on a monotone ramp that ends beyond every earlier peak of its sign (the
    run's torque before it, from 0) by more than ``margin`` of that peak — the first time the run
    loads that far that way. Ramps are split at turns of 5 % of the torque's range (as the cycle
    classes': smaller cycles' turns are not ramps of their own)."""
    tau = np.asarray(torque_Nm, float)
    out = np.zeros(tau.size, dtype=bool)
    if tau.size < 2:
        return out
    smooth, segments = monotone_segments(tau, reversal_fraction=0.05)
    peak = {1: 0.0, -1: 0.0}
    for a, b, direction in segments:
        reach = direction * float(smooth[b])
        if reach > (1.0 + margin) * peak[direction]:
            out[a:b + 1] = True
        peak[direction] = max(peak[direction], reach)
    return out


def _split_first_excursions(torque_Nm, min_samples: int) -> tuple[np.ndarray, int | None]:
    """(:func:`excursion_classes`, the first excursions' class or None when not split off)."""
    classes = amplitude_classes(torque_Nm, min_samples=min_samples)
    first = first_excursions(torque_Nm) & (classes == 0)
    if np.sum(first) < min_samples or np.sum((classes == 0) & ~first) < min_samples:
        return classes, None
    index = int(classes.max()) + 1
    classes = classes.copy()
    classes[first] = index
    return classes, index


def excursion_classes(torque_Nm, min_samples: int = CLASS_MIN_SAMPLES) -> np.ndarray:
    """:func:`amplitude_classes` with the first excursions of the largest cycles
    (:func:`first_excursions`) a class of their own, numbered after the others — when both they
    and the repeats have ``min_samples``; class 0 stays the largest cycles' repeats."""
    return _split_first_excursions(torque_Nm, min_samples)[0]


def first_excursion_index(torque_Nm, min_samples: int = CLASS_MIN_SAMPLES) -> int | None:
    """The class :func:`excursion_classes` gives the first excursions, None when they are not
    split off."""
    return _split_first_excursions(torque_Nm, min_samples)[1]


def conditioning_keep(torque_Nm, min_samples: int = CLASS_MIN_SAMPLES) -> np.ndarray:
    """Per sample: False on the first excursions of the largest cycles when they are split off
    (:func:`excursion_classes`: both they and the repeats have ``min_samples``), else True —
    the samples a fit with ``NoiseOptions.first_excursion_conditioning`` keeps in its likelihood."""
    classes, first = _split_first_excursions(torque_Nm, min_samples)
    return np.ones(classes.size, dtype=bool) if first is None else classes != first


def repeats_first(shape, classes, first: int | None) -> np.ndarray:
    """``shape`` with the first excursions' share (class ``first``) at least the repeats' (1): a
    first excursion is never weighed above the repeats. The plug-in levels weigh down whichever
    class the model draws worse, and where the first excursions outnumber the repeats (one large
    cycle after the play ramps) the model follows them and the repeats would be weighed down —
    measured on the friction bench with its first excursion given a softer twist: share 0.33,
    the stiffness moved further from the clean fit's than without the class."""
    shape = np.asarray(shape, float)
    if first is None:
        return shape
    return np.where(np.asarray(classes) == first, np.maximum(shape, 1.0), shape)


def class_noise_shape(residual_rad, classes, floor_rad: float = 0.0, keep=None) -> np.ndarray:
    """Per sample: its class's noise level over the largest cycles' (class 0), from the mean
    squared residual above the encoder floor in each class (over the samples where ``keep``,
    the likelihood's), clipped to :data:`CLASS_SHARE_RANGE`."""
    e2 = np.asarray(residual_rad, float) ** 2
    classes = np.asarray(classes, int)
    keep = np.ones(classes.size, dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    level = np.array([max(np.mean(e2[(classes == k) & keep]) - float(floor_rad) ** 2, 0.0)
                      if np.any((classes == k) & keep) else 0.0 for k in range(int(classes.max()) + 1)])
    if not level[0] > 0:
        return np.ones(classes.size)
    share = np.clip(np.sqrt(level / level[0]), *CLASS_SHARE_RANGE)
    return share[classes]


@eqx.filter_jit
def _residuals(problem, u):
    return problem.residuals(u)  # jitted: eagerly, every scan compiles anew on each call


def run_classes(problem) -> list[np.ndarray]:
    """Per run of ``problem``: the cycle class of each sample (hysteresis runs, from the drive
    torque; with ``problem.first_excursion_class`` the first excursions apart,
    :func:`excursion_classes`); TE runs one class."""
    classes = excursion_classes if problem.first_excursion_class else amplitude_classes
    return [classes(np.asarray(inp.torque_Nm)) if isinstance(inp, m.HysteresisInput)
            else np.zeros(len(y), dtype=int) for inp, y in zip(problem.inputs, problem.y)]


def refit_with_class_noise(problem, map_result, iterations: int = CLASS_ITERATIONS, **fit_map_kwargs):
    """(problem with the class shares at its optimum, its MAP): ``iterations`` rounds of reading
    the classes' levels from the residuals at the MAP (:func:`class_noise_shape`) and refitting
    from there (``fit_map`` warm-started at the previous optimum, its other arguments
    ``fit_map_kwargs``). ``problem`` must carry a noise shape (``NoiseOptions.cycle_class_noise``)."""
    from ._map import fit_map

    if problem.noise_shape is None:
        raise ValueError("refit_with_class_noise: the problem has no noise shape; build it with "
                         "NoiseOptions(cycle_class_noise=True)")
    classes = run_classes(problem)
    firsts = [first_excursion_index(np.asarray(inp.torque_Nm))
              if problem.first_excursion_class and isinstance(inp, m.HysteresisInput) else None
              for inp in problem.inputs]
    for _ in range(iterations):
        residuals = _residuals(problem, jnp.asarray(map_result.u))
        shape = [jnp.asarray(repeats_first(class_noise_shape(np.asarray(e), c, float(f), kept), c, k))
                 for e, c, f, k, kept in zip(residuals, classes, np.asarray(problem.floors), firsts,
                                             problem.kept_samples())]
        problem = eqx.tree_at(lambda p: p.noise_shape, problem, shape)
        map_result = fit_map(problem, map_result.run_names, n_starts=0, warm_starts=[map_result.u], **fit_map_kwargs)
    return problem, map_result


def class_shares(problem) -> list[list[float]]:
    """Per run: each cycle class's noise level over the largest cycles' (class 0 first)."""
    out = []
    for c, w in zip(run_classes(problem), problem.noise_shape or [None] * len(problem.y)):
        w = np.ones(c.size) if w is None else np.asarray(w)
        out.append([float(w[c == k][0]) for k in range(int(c.max()) + 1)])
    return out
