"""Separated modes among particles, and how far the particles have mixed within them.

Tempered SMC's moves leave each tempered density invariant, but an HMC or random-walk move
rarely crosses between modes separated by many of their widths. The particles then keep the
mode resampling put them in, and a coordinate that separates the modes stays correlated with its
start however well the particles mix inside each mode — while the share of particles in each
mode is set by the tempering's weights, which is what SMC is for (Del Moral, Doucet & Jasra
2006). :func:`separated_modes` finds such modes (k-means clusters each standing apart from its nearest,
along the line between their centres, by :data:`SEPARATED_MODES_SD` of their own spread);
:func:`within_mode_correlations` measures the decorrelation inside them.
"""

from __future__ import annotations

import numpy as np
from scipy.cluster.vq import kmeans2

#: two groups are separate modes when their centres lie this many pooled sd apart along the
#: line between them (two halves of one Gaussian split by two-means: 2.7; of a uniform: 3.5)
SEPARATED_MODES_SD = 5.0
#: at most this many modes are looked for
MAX_MODES = 4
#: a mode holds at least this share of the particles (and 10 of them)
MIN_MODE_SHARE = 0.05
#: k-means runs from this many seeded k-means++ starts, the best kept
KMEANS_STARTS = 4


def _kmeans(z: np.ndarray, k: int) -> np.ndarray:
    """Labels of the best of :data:`KMEANS_STARTS` seeded k-means runs (least within-cluster sum
    of squares): the same particles give the same labels."""
    best, best_ss = None, np.inf
    for seed in range(KMEANS_STARTS):
        centres, labels = kmeans2(z, k, minit="++", seed=np.random.default_rng(seed))
        ss = float(((z - centres[labels]) ** 2).sum())
        if ss < best_ss:
            best, best_ss = labels, ss
    return best


def _apart(a: np.ndarray, b: np.ndarray) -> float:
    """How far groups ``a`` and ``b`` stand apart: the distance between their centres along the
    line joining them, in their pooled sd along it."""
    direction = b.mean(axis=0) - a.mean(axis=0)
    norm = np.linalg.norm(direction)
    if norm == 0:
        return 0.0
    pa, pb = a @ direction / norm, b @ direction / norm
    pooled = np.sqrt((pa.var() * len(pa) + pb.var() * len(pb)) / (len(pa) + len(pb)))
    return float(np.inf if pooled == 0 else (pb.mean() - pa.mean()) / pooled)


def separated_modes(x: np.ndarray) -> np.ndarray:
    """Mode label (0 … k − 1) of each row of ``x`` (particles × the coordinates to look in):
    all 0 when the particles sit in one mode. The labels are those of the k-means clustering
    (k ≤ :data:`MAX_MODES`, coordinates standardised) with the most clusters of which every one
    holds :data:`MIN_MODE_SHARE` of the particles and stands :data:`SEPARATED_MODES_SD` apart
    from its nearest; where none does (more modes than that, or none), one mode — the stricter
    reading. Give it the coordinates that may separate modes (tempered SMC: those that remember
    their start): in k-means every standardised coordinate counts alike, and many of one mode's
    spread hide a split along one."""
    x = np.asarray(x, float)
    n = len(x)
    sd = x.std(axis=0)
    z = (x - x.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
    minimum = max(10, int(np.ceil(MIN_MODE_SHARE * n)))
    found = np.zeros(n, int)
    for k in range(2, MAX_MODES + 1):
        if n < k * minimum:
            break
        labels = _kmeans(z, k)
        groups = [z[labels == i] for i in range(k)]
        if min(len(g) for g in groups) < minimum:
            continue
        centres = np.array([g.mean(axis=0) for g in groups])
        nearest = [min((j for j in range(k) if j != i), key=lambda j: np.linalg.norm(centres[j] - centres[i]))
                   for i in range(k)]
        if all(_apart(groups[i], groups[j]) >= SEPARATED_MODES_SD for i, j in enumerate(nearest)):
            found = labels
    return found


def within_mode_correlations(start: np.ndarray, now: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """|correlation| of each coordinate between the particles' positions at ``start`` and
    ``now``, each taken from its mode's mean (``labels``: each particle's mode), pooled over the
    modes; 0 for a coordinate that does not vary within them. With one mode: the plain
    correlation."""
    a = np.asarray(start, float).copy()
    b = np.asarray(now, float).copy()
    for k in np.unique(labels):
        m = labels == k
        a[m] -= a[m].mean(axis=0)
        b[m] -= b[m].mean(axis=0)
    den = np.sqrt((a**2).sum(axis=0) * (b**2).sum(axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, np.abs((a * b).sum(axis=0)) / den, 0.0)


def correlations_with_start(start: np.ndarray, now: np.ndarray, decorrelation: float) -> tuple[np.ndarray, np.ndarray]:
    """(|correlation| per coordinate, mode labels): the plain correlations of the particles'
    positions ``now`` with ``start``; where one is above ``decorrelation`` the modes are looked
    for among the coordinates above it, and where there are several the correlations are read
    within them (:func:`within_mode_correlations`)."""
    labels = np.zeros(len(now), int)
    by_coordinate = within_mode_correlations(start, now, labels)
    if np.max(by_coordinate, initial=0.0) > decorrelation:  # modes looked for only where it matters
        found = separated_modes(np.asarray(now)[:, by_coordinate > decorrelation])
        if found.max() > 0:
            labels, by_coordinate = found, within_mode_correlations(start, now, found)
    return by_coordinate, labels
