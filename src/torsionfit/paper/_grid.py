"""The test under all operating conditions (paper §3.3, §4.4): TE runs over a grid of load
torque × output speed on the virtual bench of a bundled campaign, evaluated the paper's way
from the data alone — K_d = τ / TE(180°) and K_t = τ / mean TE over a revolution, TE against
the encoders' zero (``metrics.te_metrics``, as for Table 6)."""

import dataclasses
from dataclasses import dataclass

import numpy as np

from .._errors import InputError
from ..bench import Bench, TESpec, simulate
from ..metrics import te_metrics

#: the grid's lowest torque as a fraction of the rated torque (K_d → 0 at no load)
MIN_TORQUE_FRACTION = 0.2


@dataclass(frozen=True)
class OperatingGrid:
    """Data-only TE evaluation over ``speed_rpm`` × ``torque_Nm``: every array is (speeds,
    torques); TE in arcmin, stiffness in N·m/arcmin. ``label`` says where the data came from."""

    torque_Nm: np.ndarray
    speed_rpm: np.ndarray
    te_180_arcmin: np.ndarray
    te_mean_arcmin: np.ndarray
    kd_Nm_per_arcmin: np.ndarray
    kt_Nm_per_arcmin: np.ndarray
    label: str

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """Paired 1-D (torque, speed) of every grid point, speed-major (rows of the arrays)."""
        t, v = np.meshgrid(self.torque_Nm, self.speed_rpm)
        return t.ravel(), v.ravel()


def grid_axes(rated_torque_Nm: float, max_speed_rpm: float, n_torques: int, n_speeds: int,
              min_speed_rpm: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Torques from 0.2·T_r to T_r and speeds from ``min_speed_rpm`` to ``max_speed_rpm``, evenly."""
    if n_torques < 2 or n_speeds < 2:
        raise InputError(f"operating grid: need at least 2 torques and 2 speeds, got {n_torques} × {n_speeds}")
    if not 0 < min_speed_rpm < max_speed_rpm:
        raise InputError(f"operating grid: need 0 < min speed < max speed, got {min_speed_rpm:g}, {max_speed_rpm:g} rpm")
    return (np.linspace(MIN_TORQUE_FRACTION * rated_torque_Nm, rated_torque_Nm, n_torques),
            np.linspace(min_speed_rpm, max_speed_rpm, n_speeds))


def grid_bench(bench: Bench, torque_Nm, speed_rpm, seed: int) -> Bench:
    """``bench`` (its reducer, instrument and truth) with its runs replaced by one forward TE
    run of one revolution per (speed, torque), speed-major, and ``seed`` for its noise."""
    runs = tuple(TESpec(name=f"te-grid-{i:02d}-{k:02d}", speed_rpm=float(v), torque_Nm=float(t), direction=1)
                 for i, v in enumerate(speed_rpm) for k, t in enumerate(torque_Nm))
    label = f"{bench.label}; TE runs over a torque × speed grid (virtual bench, seed {seed})"
    return dataclasses.replace(bench, runs=runs, seed=seed, label=label)


def evaluate_grid(campaign, torque_Nm, speed_rpm) -> OperatingGrid:
    """K_d, K_t and the TE levels of a :func:`grid_bench` campaign, from the data alone."""
    torque_Nm, speed_rpm = np.asarray(torque_Nm, float), np.asarray(speed_rpm, float)
    shape = (len(speed_rpm), len(torque_Nm))
    if len(campaign.te_runs) != shape[0] * shape[1]:
        raise InputError(f"operating grid: {len(campaign.te_runs)} TE runs for a {shape[0]} × {shape[1]} grid")
    values = {k: [] for k in ("te_180", "te_mean", "kd", "kt")}
    for run in campaign.te_runs:
        m = te_metrics(run)
        for k in values:
            values[k].append(m[k]["value"])
    arr = {k: np.asarray(v).reshape(shape) for k, v in values.items()}
    return OperatingGrid(torque_Nm, speed_rpm, arr["te_180"], arr["te_mean"], arr["kd"], arr["kt"], campaign.notes)


def simulate_grid(bench: Bench, torque_Nm, speed_rpm, seed: int) -> OperatingGrid:
    """Run the grid on ``bench``'s virtual reducer and evaluate it (:func:`evaluate_grid`)."""
    campaign = simulate(grid_bench(bench, torque_Nm, speed_rpm, seed)).campaign
    return evaluate_grid(campaign, torque_Nm, speed_rpm)
