"""Simulate a campaign on the virtual bench: the forward model plus sensor models."""

import dataclasses
from dataclasses import dataclass

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._x64 import in_float64
from .. import model as m
from ..model import model_with_effects as truth_model
from .._errors import InputError
from ..io import Campaign, HysteresisRun, TransmissionErrorRun, reference_temperature_C
from ..metrics._hysteresis import small_cycle_rows
from ..units import ANGLE_UNITS
from ._config import Bench, HysteresisSpec, TESpec, te_tests

_ARCSEC = ANGLE_UNITS["arcsec"]
_LINEAR_DEFAULTS = ("angle_offset", "te_offset", "drift", "kin_cos", "kin_sin")


@eqx.filter_jit
def _true_components(model: m.CampaignModel, truth: dict, inputs: list) -> list:
    """The forward model's components per run (rad), compiled as one program. Run op by op, it
    took longer even for a single campaign, and more for each further campaign of that shape.
    Measured side by side on 2 cores: the SYNTHETIC 10 001-sample loop took 1.3 s against 0.4 s
    for the first campaign and 0.07–0.09 s against 0.01–0.02 s for each further one; the ten-run
    TE export took 2.4 s against 1.0 s for the first."""
    return model.components(truth, inputs)


@dataclass(frozen=True, eq=False)
class Simulation:
    """A simulated campaign with the truth that made it (SI parameters and components)."""

    campaign: Campaign
    model: m.CampaignModel
    truth: dict
    components: list  # per run: dict of true components (rad), noise-free
    measured_torque_true: list  # per run: the true (noise-free) torque driving the model, N·m


def five_step_protocol(peak_Nm, rate_Nm_per_s, sample_rate_Hz, cycles=1, dwell_s=0.0, play_cycles=0, play_torque_Nm=None):
    """Time and torque of the paper's protocol: 0→+P→0→−P→0→+P (steps 1–5), with
    ``cycles − 1`` repeats of steps 2–5 and an optional dwell at each peak. ``play_cycles``
    small cycles 0→+x→−x→0 (x = ``play_torque_Nm``) come first, as a bench runs its play
    ramps before the stiffness ramps; the dwell applies to the peaks ±P only."""
    levels = [0.0]
    for _ in range(play_cycles):
        levels += [play_torque_Nm, -play_torque_Nm, 0.0]
    levels += [peak_Nm, 0.0, -peak_Nm, 0.0, peak_Nm]
    for _ in range(cycles - 1):
        levels += [0.0, -peak_Nm, 0.0, peak_Nm]
    knots_t, knots_tau, t = [0.0], [0.0], 0.0
    for prev, nxt in zip(levels[:-1], levels[1:]):
        t += abs(nxt - prev) / rate_Nm_per_s
        knots_t.append(t)
        knots_tau.append(nxt)
        if dwell_s > 0 and abs(nxt) == peak_Nm:
            t += dwell_s
            knots_t.append(t)
            knots_tau.append(nxt)
    n = int(round(knots_t[-1] * sample_rate_Hz)) + 1
    time = np.linspace(0.0, knots_t[-1], n)
    return time, np.interp(time, knots_t, knots_tau)


def _complete_truth(model: m.CampaignModel, truth: dict, where: str) -> dict:
    """Check the truth names every physical parameter; linear ones default to zero."""
    params = {}
    for p in model.parameters():
        if p.name in truth:
            value = np.asarray(truth[p.name], float)
            if p.size > 1 or p.linear:
                value = np.broadcast_to(value, (p.size,)).copy() if value.size in (1, p.size) else None
                if value is None:
                    raise InputError(f"{where} [truth].{p.name}: expected 1 or {p.size} values")
            params[p.name] = jnp.asarray(value)
        elif p.name in _LINEAR_DEFAULTS:
            params[p.name] = jnp.zeros(p.size)
        else:
            raise InputError(f"{where} [truth]: missing parameter {p.name!r} ({p.description}, SI unit {p.unit})")
    extra = set(truth) - {p.name for p in model.parameters()}
    if extra:
        raise InputError(f"{where} [truth]: {sorted(extra)[0]!r} is not a parameter of the model these [effects] describe")
    return params


def _ar1_noise(rng, n, sd, phi):
    if sd <= 0:
        return np.zeros(n)
    e = rng.normal(0.0, sd * np.sqrt(1 - phi**2), n)
    x = np.empty(n)
    x[0] = rng.normal(0.0, sd)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


def _jumps(rng, n, share, size):
    """Isolated jumps: ``share`` of n samples (at random) moved by ±``size``; no draw at all
    when off, so a bench without jumps reads the same numbers as before they existed."""
    out = np.zeros(n)
    if share <= 0 or size <= 0:
        return out
    idx = rng.choice(n, size=int(round(share * n)), replace=False)
    out[idx] = rng.choice([-1.0, 1.0], size=idx.size) * size
    return out


def _quantise(x, step):
    return x if step is None else np.round(x / step) * step


@in_float64
def simulate(bench: Bench, seed: int | None = None) -> Simulation:
    """Simulate every run of ``bench`` with its sensors; ``seed`` overrides the bench's."""
    rng = np.random.default_rng(bench.seed if seed is None else seed)
    where = str(bench.path or "bench")
    kinds = ["hysteresis" if isinstance(r, HysteresisSpec) else "transmission_error" for r in bench.runs]
    model = truth_model(kinds, bench.effects, bench.reducer.rated_torque_Nm)
    export = bench.te_export
    tests = te_tests(bench.runs) if export is not None else []
    truth_table = dict(bench.truth)
    if export is not None:  # encoders re-zeroed before every test: one TE zero per test
        model = dataclasses.replace(model, te_zero_groups=len(tests))
        if export.zero_shift_arcmin:
            truth_table["te_offset"] = [v * _ARCSEC * 60.0 for v in export.zero_shift_arcmin]
    truth = _complete_truth(model, truth_table, where)
    ins = bench.instrument
    res = None if ins.encoder_resolution_arcsec is None else ins.encoder_resolution_arcsec * _ARCSEC
    torque_sd = bench.noise.torque_sd_Nm if bench.noise.torque_sd_Nm is not None else (ins.torque_sd_Nm or 0.0)
    offset = float(truth["torque_offset"]) if "torque_offset" in truth else 0.0
    play_offset = float(truth["play_torque_offset"]) if "play_torque_offset" in truth else 0.0
    ripple = bench.effects.get("encoder_ripple")
    reference_C = reference_temperature_C(spec.temperature_C for spec in bench.runs)
    if model.temperature is not None:
        missing = [spec.name for spec in bench.runs if spec.temperature_C is None]
        if missing:
            raise InputError(f"{where} runs {missing[0]!r}: temperature_dependence needs every run's temperature_C")

    def delta_K(spec):
        """The run's temperature above the campaign's reference (as a fit will read it)."""
        return 0.0 if spec.temperature_C is None else spec.temperature_C - reference_C

    def measured_angle(theta, position=0.0):
        """Output encoder at ``position + theta``: sub-division ripple (if on), extra noise,
        quantisation. Returns the reading relative to ``position``."""
        if ripple:
            amp = float(ripple.get("amplitude_arcsec", 0.0)) * _ARCSEC
            period = float(ripple.get("period_arcsec", 60.0)) * _ARCSEC
            theta = theta + amp * np.sin(2 * np.pi * (position + theta) / period)
        theta = theta + _ar1_noise(rng, len(theta), bench.noise.angle_sd_arcsec * _ARCSEC, bench.noise.angle_ar1)
        theta = theta + _jumps(rng, len(theta), bench.noise.jump_share, bench.noise.jump_arcsec * _ARCSEC)
        return _quantise(position + theta, res) - position

    inputs, drives, readings = [], [], []
    for spec in bench.runs:
        if isinstance(spec, HysteresisSpec):
            t, tau = five_step_protocol(spec.peak_torque_Nm, spec.loading_rate_Nm_per_s, ins.sample_rate_Hz, spec.cycles,
                                       spec.dwell_s, spec.play_cycles, spec.play_torque_Nm)
            # the play ramps' samples, as a fit will mark them (from the torque alone: the angle
            # is not simulated yet, and the grouping of cycles does not read it)
            small = small_cycle_rows(t, tau, tau, name=spec.name)
            sensor = tau + offset + play_offset * small  # the sensor reads true torque + offset(s)
            inputs.append(m.hysteresis_input(t, sensor, delta_K(spec), small))
            drives.append(tau)
            readings.append(sensor)
        else:
            # an export's logger runs at a fixed clock: its samples per revolution follow the speed
            per_rev = bench.te_samples_per_rev if export is None else export.sample_rate_Hz * 60.0 / spec.speed_rpm
            n = int(round(spec.revolutions * per_rev))
            # samples are clocked, not triggered by position: each lands within ±¼ step of its
            # nominal angle, so quantisation errors differ from sample to sample
            step = 2 * np.pi / per_rev
            # an export's forward revolution logs a sample more than its backward one (the NaN pad)
            extra = int(export is not None and spec.direction > 0)
            phi = np.linspace(0.0, 2 * np.pi * spec.revolutions * (n + extra) / n, n + 1 + extra)
            phi = phi + rng.uniform(-0.25, 0.25, n + 1 + extra) * step
            if spec.direction < 0:
                phi = phi[::-1]
            clock = np.arange(len(phi)) * step / (spec.speed_rpm * 2 * np.pi / 60)  # clocked samples
            group = tests.index((spec.torque_Nm, spec.speed_rpm, spec.temperature_C)) if tests else 0
            inputs.append(m.te_input(phi, spec.torque_Nm + offset, spec.speed_rpm, spec.direction, clock, group, delta_K(spec)))
            drives.append(np.full(len(phi), spec.torque_Nm))
            readings.append(drives[-1] + offset)
    comps = _true_components(model, truth, inputs)

    runs, hyst_i = [], 0
    for spec, inp, c, tau, reading in zip(bench.runs, inputs, comps, drives, readings):
        total = np.asarray(c["total"])
        if isinstance(spec, HysteresisSpec):
            # the locked loop sits at one output position: its kinematic error is a constant
            if model.kinematic is not None:
                total = total + float(model.kinematic(truth, jnp.asarray([np.deg2rad(spec.position_deg)]))[0])
            hyst_i += 1
            runs.append(HysteresisRun(
                name=spec.name,
                time_s=np.asarray(inp.time_s),
                torque_Nm=reading + rng.normal(0.0, torque_sd, len(tau)),
                angle_rad=measured_angle(total, np.deg2rad(spec.position_deg)),
                loading_rate_Nm_per_s=spec.loading_rate_Nm_per_s,
                source="synthetic",
                # a loop below the rated torque declares its nominal peak (the reader checks it)
                peak_torque_Nm=None if spec.peak_torque_Nm == bench.reducer.rated_torque_Nm else spec.peak_torque_Nm,
                nominal_temperature_C=spec.temperature_C,
            ))
        else:
            phi = np.asarray(inp.output_angle_rad)
            # TE = θ_out − θ_in/R from two quantised encoders (θ_out = φ, θ_in = R(φ − TE));
            # the input encoder is R× finer once referred to the output
            ratio = bench.reducer.ratio or 1.0
            theta_out = phi + measured_angle(np.zeros_like(phi), phi)
            theta_in = _quantise(ratio * (phi - total), res)
            te = theta_out - theta_in / ratio
            runs.append(TransmissionErrorRun(
                name=spec.name,
                output_angle_rad=phi,
                te_rad=te,
                # the nominal load is what the torque sensor reads (true load + offset), as the
                # model's torque_offset assumes
                torque_Nm=spec.torque_Nm + offset,
                speed_rpm=spec.speed_rpm,
                direction=spec.direction,
                time_s=np.asarray(inp.time_s),
                # an export logs no torque series (its load is the test's nominal one)
                torque_series_Nm=None if export else reading + rng.normal(0.0, torque_sd, len(tau)),
                source="synthetic",
                zero_group=None if export is None else export_stem(bench.reducer, tests[int(inp.zero_group)]),
                nominal_temperature_C=spec.temperature_C,
            ))
    campaign = Campaign(reducer=bench.reducer, instrument=bench.instrument, runs=tuple(runs), notes=bench.label)
    return Simulation(campaign=campaign, model=model, truth=truth, components=comps, measured_torque_true=drives)


def export_stem(reducer, test: tuple) -> str:
    """File stem (and zero group) of one test of a TE bench export: motor speed and load, as
    such benches name their files (``TE_486rpm_500Nm``, ``_40C`` with a temperature)."""
    torque, speed, temperature = test
    stem = f"TE_{speed * reducer.ratio:g}rpm_{torque:g}Nm"
    return stem if temperature is None else f"{stem}_{temperature:g}C"
