"""An independent virtual bench, written in plain NumPy without torsionfit's model code, for
testing torsionfit on loops it was not built from. Everything it writes is SYNTHETIC.

Two reducers, each with shapes torsionfit's model does not have:

- :class:`TorqueSideReducer`, the arrangement of the physics torsionfit models (friction between
  the applied torque and the mesh, ``τ_m = τ − T_fric``), its parts built differently: several
  Dahl elements with their own saturation torques (not Maxwell-slip play operators), each level
  growing with the transmitted torque, integrated by explicit sub-steps; a hardening spring
  ``K·θ·(1 + (θ/θ_s)²) = τ_m`` (not a power law); the gap crossed along a cubic smoothstep of the
  mesh torque (not a tanh);
- :class:`TwistSideReducer`, an arrangement outside torsionfit's physics: friction on the
  *twist*, a hardening spring in parallel with Maxwell-slip elements of finite stiffness that
  stick until their force reaches a slip level (generalized Maxwell-slip; the applied torque is
  their sum, solved for θ at every sample), the slip levels growing with the load; the gap
  crossed along a smoothstep of the torque through a play operator (a relay).

Both are read like the measured files: an encoder of step ``encoder_step_rad`` with white noise
below it, the torque (from motor current) with white noise of its own, the angle in output
revolutions with an arbitrary offset. The torque program imitates the measured cycloidal files
(``../shared/data/cycloidal-jv``): five small play ramps (test_nr 0–4) and three large stiffness
ramps (test_nr 100–102), one file.

    .venv/bin/python benchmarks/independent_bench.py -o /tmp/bench                 # torque side, load-dependent, 4 elements
    .venv/bin/python benchmarks/independent_bench.py -o /tmp/bench --clean         # one element, constant level, linear spring
    .venv/bin/python benchmarks/independent_bench.py -o /tmp/bench --twist-side    # friction on the twist
"""

import argparse
import dataclasses
import math
from pathlib import Path

import numpy as np


@dataclasses.dataclass(frozen=True)
class TorqueSideReducer:
    """A reducer's truth (SI units: N·m, rad), friction between the applied torque and the mesh.

    Friction ``Σ_i T_i·z_i``, each Dahl state ``dz_i = (|dτ|/τ_d,i)(sgn dτ − z_i)``, level
    ``T_i = T0_i + μ·(T0_i/ΣT0)·|τ|`` and saturation torque ``τ_d,i = r_i·T_i`` (``r_i ≥ 2``: after
    a reversal the mesh torque may stay put, never move against the applied torque); mesh torque ``τ_m = τ − Σ_i T_i·z_i``; elastic twist θ_e
    from ``K·θ_e·(1 + (θ_e/θ_s)²) = τ_m``; the gap ``(β/2)·(2·S(τ_m/w + 1/2) − 1)`` with S the cubic
    smoothstep; twist ``θ_e + θ_g``."""

    # the measured printed cycloidal reducers' scale: about 0.08°/N·m, ±40 N·m, play 0.1–3°
    stiffness_Nm_per_rad: float = 800.0  # K: small-twist elastic stiffness
    stiffening_twist_rad: float = 0.08  # θ_s: the spring's torque grows by (θ/θ_s)² (inf: linear)
    element_level_Nm: tuple = (0.4, 1.0, 2.0)  # T0_i: the elements' levels at zero load
    element_dahl_ratio: tuple = (2.2, 3.0, 6.0)  # r_i: each element's saturation torque over its level
    level_load_coefficient: float = 0.15  # μ: the summed level grows by μ·|τ|
    gap_rad: float = math.radians(1.0)  # β: the whole lost motion
    gap_width_Nm: float = 1.0  # w: mesh-torque span of the crossing

    def levels(self, torque_Nm):
        t0 = np.asarray(self.element_level_Nm, float)
        return t0 + self.level_load_coefficient * (t0 / t0.sum()) * abs(torque_Nm)

    def elastic_twist(self, mesh_torque_Nm: np.ndarray) -> np.ndarray:
        """θ_e solving K·θ·(1 + (θ/θ_s)²) = τ_m, by bisection (the left side increases in θ)."""
        k, s = self.stiffness_Nm_per_rad, self.stiffening_twist_rad
        lo = np.full(mesh_torque_Nm.shape, -np.abs(mesh_torque_Nm).max() / k - 1e-9)
        hi = -lo
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            low = k * mid * (1.0 + (mid / s) ** 2) < mesh_torque_Nm
            lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
        return 0.5 * (lo + hi)


def clean_torque_side_reducer() -> TorqueSideReducer:
    """The torque-side reducer with what torsionfit's base model has: one Dahl element at a
    constant level, a linear spring (the gap still a smoothstep)."""
    return dataclasses.replace(TorqueSideReducer(), element_level_Nm=(2.0,), element_dahl_ratio=(3.0,),
                               level_load_coefficient=0.0, stiffening_twist_rad=math.inf)


@dataclasses.dataclass(frozen=True)
class TwistSideReducer:
    """A reducer's truth (SI units: N·m, rad)."""

    # the measured printed cycloidal reducers' scale: about 0.08°/N·m, ±40 N·m, play 0.1–3°
    stiffness_Nm_per_rad: float = 800.0  # K: small-twist elastic stiffness
    stiffening_twist_rad: float = 0.08  # θ_s: the spring's torque grows by (θ/θ_s)²
    element_stiffness_Nm_per_rad: tuple = (2000.0, 1500.0, 1000.0, 600.0)  # k_i
    element_slip_Nm: tuple = (0.3, 0.8, 1.6, 3.0)  # F0_i: slip levels at zero load
    slip_load_coefficient: float = 0.15  # μ: ΣF grows by μ·|τ|
    gap_rad: float = math.radians(1.0)  # β: the whole lost motion
    gap_hold_Nm: float = 1.0  # half-width of the play operator the gap follows the torque through
    gap_width_Nm: float = 1.5  # the torque span of the crossing (cubic smoothstep)

    def slip_levels(self, torque_Nm: float) -> np.ndarray:
        f0 = np.asarray(self.element_slip_Nm, float)
        return f0 + self.slip_load_coefficient * (f0 / f0.sum()) * abs(torque_Nm)

    def spring_torque(self, twist_rad):
        return self.stiffness_Nm_per_rad * twist_rad * (1.0 + (twist_rad / self.stiffening_twist_rad) ** 2)


def clean_twist_side_reducer() -> TwistSideReducer:
    """The twist-side reducer with one element at a constant slip level: no load dependence, no spread."""
    return dataclasses.replace(TwistSideReducer(), element_stiffness_Nm_per_rad=(2000.0,), element_slip_Nm=(2.0,),
                               slip_load_coefficient=0.0)


def torque_program(rate_Hz: float = 50.0, play_amplitude_Nm: float = 4.0, large_amplitude_Nm: float = 40.0,
                   n_play: int = 5, n_large: int = 3, play_period_s: float = 4.0, large_period_s: float = 20.0):
    """(time_s, torque_Nm, test_nr): triangle cycles 0 → +A → −A → 0, the play ramps first."""
    pieces, numbers = [], []
    for nr, amplitude, period in ([(k, play_amplitude_Nm, play_period_s) for k in range(n_play)]
                                  + [(100 + k, large_amplitude_Nm, large_period_s) for k in range(n_large)]):
        phase = np.arange(int(round(period * rate_Hz))) / (period * rate_Hz)
        pieces.append(amplitude * np.interp(phase, [0.0, 0.25, 0.75, 1.0], [0.0, 1.0, -1.0, 0.0]))
        numbers.append(np.full(phase.size, nr))
    torque = np.concatenate(pieces)
    return np.arange(torque.size) / rate_Hz, torque, np.concatenate(numbers)


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


#: explicit sub-steps per sample of the Dahl states: the torque changes by well under a tenth of
#: the smallest saturation torque per sub-step at the rates of :func:`torque_program`
SUB_STEPS = 20


def _torque_side(reducer: TorqueSideReducer, torque_Nm: np.ndarray) -> np.ndarray:
    """Noiseless twist (rad) of a :class:`TorqueSideReducer`, from rest (every z_i = 0)."""
    ratio = np.asarray(reducer.element_dahl_ratio, float)
    z = np.zeros_like(ratio)
    friction = np.empty(torque_Nm.size)
    previous = torque_Nm[0]
    for n, tau in enumerate(torque_Nm):
        step = (tau - previous) / SUB_STEPS
        tau_d = ratio * reducer.levels(tau)
        for _ in range(SUB_STEPS):
            z = z + abs(step) / tau_d * (np.sign(step) - z)
        previous = tau
        friction[n] = np.sum(reducer.levels(tau) * z)
    mesh = torque_Nm - friction
    gap = 0.5 * reducer.gap_rad * (2.0 * _smoothstep(mesh / reducer.gap_width_Nm + 0.5) - 1.0)
    return reducer.elastic_twist(mesh) + gap


def simulate_twist(reducer, torque_Nm: np.ndarray) -> np.ndarray:
    """Noiseless twist (rad) of either reducer along the torque sequence, from rest."""
    torque_Nm = np.asarray(torque_Nm, float)
    return _torque_side(reducer, torque_Nm) if isinstance(reducer, TorqueSideReducer) else _twist_side(reducer, torque_Nm)


def _twist_side(reducer, torque_Nm: np.ndarray) -> np.ndarray:
    """Noiseless twist (rad) of a :class:`TwistSideReducer`, from rest (anchors at zero, gap centred)."""
    k = np.asarray(reducer.element_stiffness_Nm_per_rad, float)
    anchor = np.zeros_like(k)
    theta = 0.0
    out = np.empty(torque_Nm.size)
    gap_torque = 0.0  # the gap's relay: a play operator of half-width gap_hold_Nm on the torque
    for n, tau in enumerate(torque_Nm):
        levels = reducer.slip_levels(tau)

        def net(th):
            return reducer.spring_torque(th) + np.sum(np.clip(k * (th - anchor), -levels, levels)) - tau

        # bisection: the net torque increases in θ (the spring's slope is positive)
        lo, hi = theta - 0.01, theta + 0.01
        while net(lo) > 0:
            lo -= 0.05
        while net(hi) < 0:
            hi += 0.05
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if net(mid) < 0 else (lo, mid)
        theta = 0.5 * (lo + hi)
        force = k * (theta - anchor)
        anchor = np.where(force > levels, theta - levels / k, np.where(force < -levels, theta + levels / k, anchor))
        gap_torque = min(max(gap_torque, tau - reducer.gap_hold_Nm), tau + reducer.gap_hold_Nm)
        gap_state = 2.0 * _smoothstep(gap_torque / reducer.gap_width_Nm + 0.5) - 1.0
        out[n] = theta + 0.5 * reducer.gap_rad * gap_state
    return out


#: one encoder step of the measured files: 2^-16 output revolution (rad)
ENCODER_STEP_RAD = 2.0 * math.pi / 2**16


def measure(twist_rad, torque_Nm, seed: int, angle_noise_rad: float = 0.3 * ENCODER_STEP_RAD,
            encoder_step_rad: float = ENCODER_STEP_RAD, torque_noise_Nm: float = 0.05, offset_rad: float = 0.37):
    """(angle_rad, torque_Nm) as a bench reads them: the twist plus an arbitrary offset and white
    noise (below one step by default), quantised to the encoder's step; the torque with white noise."""
    rng = np.random.default_rng(seed)
    angle = offset_rad + twist_rad + rng.normal(0.0, angle_noise_rad, twist_rad.size)
    return encoder_step_rad * np.round(angle / encoder_step_rad), torque_Nm + rng.normal(0.0, torque_noise_Nm, torque_Nm.size)


MANIFEST = """\
# SYNTHETIC: written by benchmarks/independent_bench.py (an independent simulator, not
# torsionfit's model), laid out like the measured cycloidal files (TIME, TORQUE, POSITION in
# output revolutions with an offset, test_nr: play ramps 0-4, stiffness ramps 100-102).
label = "SYNTHETIC loop of benchmarks/independent_bench.py ({name}, seed {seed})"

[reducer]
name = "independent-{name}"
rated_torque_Nm = 20.0

[instrument]
encoder_resolution_arcsec = {step_arcsec!r}

[[runs]]
name = "{name}"
kind = "hysteresis"
file = "{name}.csv"
peak_torque_Nm = 40.0

[runs.columns]
time = "TIME"
torque = "TORQUE"
angle = "POSITION"

[runs.units]
angle = "rev"
"""


def record(reducer, seed: int, rate_Hz: float = 50.0, noisy: bool = True, play_torque_zero_Nm: float = 0.0):
    """(time_s, applied torque, test_nr, twist_rad, angle_rad read, torque_Nm read) of one
    simulated and measured record; ``noisy=False``: the noiseless twist, unquantised.
    ``play_torque_zero_Nm``: the torque reading's zero on the play ramps (test_nr < 100) moved by
    that much against the stiffness ramps' (a motor-current torque estimate)."""
    time_s, torque, test_nr = torque_program(rate_Hz)
    twist = simulate_twist(reducer, torque)
    angle, torque_read = measure(twist, torque, seed) if noisy else measure(twist, torque, seed, 0.0, 1e-12, 0.0)
    return time_s, torque, test_nr, twist, angle, torque_read + play_torque_zero_Nm * (test_nr < 100)


def write_campaign(folder: Path, reducer, name: str, seed: int, rate_Hz: float = 50.0,
                   noisy: bool = True, play_torque_zero_Nm: float = 0.0) -> Path:
    """Simulate, measure and write ``folder/<name>.csv`` and ``folder/campaign.toml``; returns the
    manifest's path. ``noisy=False``: the noiseless twist, unquantised (the truth a metric's
    definition gives), the manifest's encoder step as with noise; ``play_torque_zero_Nm`` as in
    :func:`record`."""
    folder.mkdir(parents=True, exist_ok=True)
    time_s, _, test_nr, _, angle, torque_read = record(reducer, seed, rate_Hz, noisy, play_torque_zero_Nm)
    with open(folder / f"{name}.csv", "w") as f:
        f.write("TIME,POSITION,TORQUE,test_nr\n")
        for row in zip(time_s, angle / (2.0 * math.pi), torque_read, test_nr):
            f.write(f"{row[0]:.4f},{float(row[1])!r},{row[2]:.5f},{row[3]}\n")
    path = folder / "campaign.toml"
    path.write_text(MANIFEST.format(name=name, seed=seed, step_arcsec=math.degrees(ENCODER_STEP_RAD) * 3600.0))
    return path


def noise_floors_rad(reducer, seed: int, rate_Hz: float = 50.0) -> tuple[float, float]:
    """(the RMS of the angle's measurement noise in the record ``write_campaign`` writes — noise
    and quantisation; the RMS of what the simulator itself leaves on that record when driven by
    the record's torque, noise included, as any model fed the read torque is), both rad. The second
    is the residual of a perfect model: the torque noise carried through a steep gap crossing and
    through the friction's memory, besides the angle noise."""
    _, _, _, twist, angle, torque_read = record(reducer, seed, rate_Hz)
    noise = angle - twist
    perfect = angle - simulate_twist(reducer, torque_read)
    return float(np.std(noise)), float(np.std(perfect))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, required=True)
    parser.add_argument("--clean", action="store_true", help="one element at a constant level (torque side: and a linear spring)")
    parser.add_argument("--twist-side", action="store_true", help="friction on the twist (generalized Maxwell-slip)")
    parser.add_argument("--noiseless", action="store_true", help="the twist without noise or quantisation")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.twist_side:
        reducer = clean_twist_side_reducer() if args.clean else TwistSideReducer()
    else:
        reducer = clean_torque_side_reducer() if args.clean else TorqueSideReducer()
    name = ("twist-side" if args.twist_side else "torque-side") + ("-clean" if args.clean else "")
    print(write_campaign(args.output, reducer, name, args.seed, noisy=not args.noiseless))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
