"""Bench files: a virtual reducer on a virtual test bench (TOML), parsed and checked.

The ``[effects]`` and ``[truth]`` tables describe the physics that generates the data; they
never reach the written campaign manifest, so a campaign can carry effects nobody declared.
"""

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .._errors import InputError
from ..io import Instrument, Reducer
from ._truth import parse_truth

EFFECTS = (
    "stiffness_nonlinearity",
    "rate_dependence",
    "kinematic_error",
    "speed_dependence",
    "asymmetry",
    "thermal_drift",
    "torque_offset",
    "play_torque_offset",  # the torque reading's zero on the play ramps apart from the larger cycles' (motor-current torque)
    "load_dependent_friction",
    "distributed_friction",
    "temperature_dependence",
    "gap_lag",  # the gap crossing trails the mesh torque through a first-order lag
    "series_compliance",  # a share of the compliance ahead of the friction; not in the catalog
    "preload_stiffening",  # a preloaded second load path below a lift-off torque (split pinwheels); not in the catalog
    "gap_preload",  # a gap held closed below a preload torque (split-pinwheel designs); not in the catalog
    "gap_hold",  # a gap held by its own friction, crossed beyond ±T_h (a relay; split pinwheels); {centred = false}: about a torque of its own
    "gap_steps",  # a gap taken up in several steps (pins of unequal clearance); not in the catalog
    "gap_relays",  # a gap crossed in held steps (relays on a grid of switches: a Preisach gap)
    "encoder_ripple",  # outside the catalog: a sub-division error periodic in the measured angle
)


@dataclass(frozen=True)
class HysteresisSpec:
    name: str
    loading_rate_Nm_per_s: float
    peak_torque_Nm: float
    cycles: int = 1  # 1 = the five-step protocol; each extra cycle repeats steps 2–5
    dwell_s: float = 0.0  # hold at each turning point
    position_deg: float = 180.0  # output position of the locked loop
    play_cycles: int = 0  # small cycles 0→+x→−x→0 before the stiffness ramps ("play ramps")
    play_torque_Nm: float | None = None  # x of the play ramps (default 5 % of the rated torque)
    temperature_C: float | None = None  # nominal temperature of the run (written as temperature_C)


@dataclass(frozen=True)
class TESpec:
    name: str
    speed_rpm: float
    torque_Nm: float
    direction: int
    revolutions: float = 1.0
    temperature_C: float | None = None  # nominal temperature of the run (written as temperature_C)


@dataclass(frozen=True)
class TEExport:
    """A TE bench that logs the way real ones do (``[te_export]`` of a bench file): one test per
    (load, speed, temperature) holding its forward and backward revolution, samples clocked at
    ``sample_rate_Hz`` (no time column), encoders re-zeroed before every test (the TE zero
    moves by ``zero_shift_arcmin[i]`` in test ``i``), written side by side by
    :func:`write_te_export`."""

    sample_rate_Hz: float
    zero_shift_arcmin: tuple[float, ...] = ()


@dataclass(frozen=True)
class Noise:
    angle_sd_arcsec: float = 0.0  # white/AR(1) angle noise on top of quantisation
    angle_ar1: float = 0.0  # AR(1) coefficient of that noise, in [0, 1)
    torque_sd_Nm: float | None = None  # default: instrument accuracy × full scale
    # isolated jumps of the angle reading: this share of the samples (chosen at random) moved by
    # ±jump_arcsec — heavy-tailed noise, as a stick-slip staircase or a gap crossed between
    # samples leaves in a measured loop's residual (what ``--student-t`` is for)
    jump_share: float = 0.0
    jump_arcsec: float = 0.0


@dataclass(frozen=True)
class Bench:
    reducer: Reducer
    instrument: Instrument
    runs: tuple[HysteresisSpec | TESpec, ...]
    truth: dict  # SI model parameters (scalars or lists)
    effects: dict = field(default_factory=dict)
    noise: Noise = Noise()
    te_samples_per_rev: int = 720
    te_export: TEExport | None = None  # log TE runs as a TE bench export (see TEExport)
    seed: int = 0
    label: str = ""
    path: Path | None = None


_TOP = {"label", "seed", "reducer", "instrument", "noise", "effects", "truth", "runs", "te_samples_per_rev", "te_export"}


def _check_keys(table: dict, allowed, where: str):
    for k in table:
        if k not in allowed:
            raise InputError(f"{where}: unknown key {k!r}; expected one of {', '.join(sorted(allowed))}")


def _num(table, key, where, default=None, positive=False, required=False):
    if key not in table:
        if required:
            raise InputError(f"{where}: missing key {key!r}")
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"{where}.{key}: expected a number, got {v!r}")
    if positive and not v > 0:
        raise InputError(f"{where}.{key}: expected a positive number, got {v!r}")
    return float(v)


def load_bench(path) -> Bench:
    """Read and check a bench file; InputError (one line) on anything wrong."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: bench file not found")
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"{path}: TOML syntax error: {err}") from None
    w = str(path)
    _check_keys(doc, _TOP, w)

    red = doc.get("reducer")
    if not isinstance(red, dict):
        raise InputError(f"{w}: missing [reducer] table")
    _check_keys(red, {"name", "rated_torque_Nm", "ratio", "max_speed_rpm"}, f"{w} [reducer]")
    reducer = Reducer(
        name=str(red.get("name", path.stem)),
        rated_torque_Nm=_num(red, "rated_torque_Nm", f"{w} [reducer]", positive=True, required=True),
        ratio=_num(red, "ratio", f"{w} [reducer]", positive=True),
        max_speed_rpm=_num(red, "max_speed_rpm", f"{w} [reducer]", positive=True),
    )
    ins = doc.get("instrument", {})
    ins_keys = {"torque_full_scale_Nm", "torque_accuracy_pct_fs", "encoder_resolution_arcsec", "sample_rate_Hz"}
    _check_keys(ins, ins_keys, f"{w} [instrument]")
    instrument = Instrument(**{k: _num(ins, k, f"{w} [instrument]", positive=True) for k in ins_keys})
    if instrument.sample_rate_Hz is None:
        raise InputError(f"{w} [instrument]: missing key 'sample_rate_Hz' (hysteresis sampling rate)")

    nz = doc.get("noise", {})
    _check_keys(nz, {"angle_sd_arcsec", "angle_ar1", "torque_sd_Nm", "jump_share", "jump_arcsec"}, f"{w} [noise]")
    noise = Noise(
        angle_sd_arcsec=_num(nz, "angle_sd_arcsec", f"{w} [noise]", 0.0),
        angle_ar1=_num(nz, "angle_ar1", f"{w} [noise]", 0.0),
        torque_sd_Nm=_num(nz, "torque_sd_Nm", f"{w} [noise]"),
        jump_share=_num(nz, "jump_share", f"{w} [noise]", 0.0),
        jump_arcsec=_num(nz, "jump_arcsec", f"{w} [noise]", 0.0),
    )
    if not 0.0 <= noise.angle_ar1 < 1.0:
        raise InputError(f"{w} [noise].angle_ar1: expected a value in [0, 1), got {noise.angle_ar1}")
    if not 0.0 <= noise.jump_share < 1.0:
        raise InputError(f"{w} [noise].jump_share: expected a share of the samples in [0, 1), got {noise.jump_share}")
    if not noise.jump_arcsec >= 0.0:
        raise InputError(f"{w} [noise].jump_arcsec: expected a jump size ≥ 0 arcsec, got {noise.jump_arcsec}")

    effects = doc.get("effects", {})
    _check_keys(effects, set(EFFECTS), f"{w} [effects]")
    truth = parse_truth(doc.get("truth", {}), f"{w} [truth]")

    runs = []
    raw_runs = doc.get("runs", [])
    if not raw_runs:
        raise InputError(f"{w}: no [[runs]]; a bench needs at least one run")
    names = set()
    for i, r in enumerate(raw_runs):
        where = f"{w} runs[{i}]"
        kind = r.get("kind")
        name = str(r.get("name", f"run-{i}"))
        if name in names:
            raise InputError(f"{where}: duplicate run name {name!r}")
        names.add(name)
        if kind == "hysteresis":
            _check_keys(r, {"name", "kind", "loading_rate_Nm_per_s", "peak_torque_Nm", "cycles", "dwell_s", "position_deg",
                            "play_cycles", "play_torque_Nm", "temperature_C"}, where)
            play_cycles = _num(r, "play_cycles", where, 0.0)
            if play_cycles < 0 or play_cycles != int(play_cycles):
                raise InputError(f"{where}.play_cycles: expected a whole number ≥ 0, got {r['play_cycles']!r}")
            peak = _num(r, "peak_torque_Nm", where, reducer.rated_torque_Nm, positive=True)
            play_torque = _num(r, "play_torque_Nm", where, 0.05 * reducer.rated_torque_Nm, positive=True)
            if play_cycles and play_torque >= peak:
                raise InputError(f"{where}.play_torque_Nm: the play ramps ({play_torque:g} N·m) must stay below the peak ({peak:g} N·m)")
            runs.append(HysteresisSpec(
                name=name,
                loading_rate_Nm_per_s=_num(r, "loading_rate_Nm_per_s", where, positive=True, required=True),
                peak_torque_Nm=peak,
                cycles=int(_num(r, "cycles", where, 1, positive=True)),
                dwell_s=_num(r, "dwell_s", where, 0.0),
                position_deg=_num(r, "position_deg", where, 180.0),
                play_cycles=int(play_cycles),
                play_torque_Nm=play_torque if play_cycles else None,
                temperature_C=_num(r, "temperature_C", where),
            ))
        elif kind == "transmission_error":
            _check_keys(r, {"name", "kind", "speed_rpm", "torque_Nm", "direction", "revolutions", "temperature_C"}, where)
            direction = r.get("direction", "forward")
            if direction not in ("forward", "backward"):
                raise InputError(f"{where}.direction: expected 'forward' or 'backward', got {direction!r}")
            runs.append(TESpec(
                name=name,
                speed_rpm=_num(r, "speed_rpm", where, positive=True, required=True),
                torque_Nm=_num(r, "torque_Nm", where, required=True),
                direction=1 if direction == "forward" else -1,
                revolutions=_num(r, "revolutions", where, 1.0, positive=True),
                temperature_C=_num(r, "temperature_C", where),
            ))
        else:
            raise InputError(f"{where}.kind: expected 'hysteresis' or 'transmission_error', got {kind!r}")
    te_export = _te_export(doc.get("te_export"), runs, reducer, w)
    label = doc.get("label") or f"SYNTHETIC data made by torsionfit simulate from {path.name}"
    if "synthetic" not in label.lower():
        label = "SYNTHETIC: " + label
    return Bench(
        reducer=reducer, instrument=instrument, runs=tuple(runs), truth=truth, effects=dict(effects),
        noise=noise, te_samples_per_rev=int(doc.get("te_samples_per_rev", 720)), te_export=te_export,
        seed=int(doc.get("seed", 0)), label=label, path=path,
    )


def te_tests(runs) -> list[tuple]:
    """The tests of a TE bench export: the distinct (torque, speed, temperature) of the TE runs,
    in order of first appearance (each test's forward and backward runs share one zero)."""
    return list(dict.fromkeys((r.torque_Nm, r.speed_rpm, r.temperature_C) for r in runs if isinstance(r, TESpec)))


def _te_export(table, runs, reducer: Reducer, w: str) -> TEExport | None:
    if table is None:
        return None
    where = f"{w} [te_export]"
    if not isinstance(table, dict):
        raise InputError(f"{where}: expected a table")
    _check_keys(table, {"sample_rate_Hz", "zero_shift_arcmin"}, where)
    if any(isinstance(r, HysteresisSpec) for r in runs):
        raise InputError(f"{where}: a TE bench export holds TE runs only; expected no hysteresis [[runs]]")
    if reducer.ratio is None:
        raise InputError(f"{where}: needs [reducer] ratio (the export names the motor speed, output speed × ratio)")
    shifts = table.get("zero_shift_arcmin", [])
    tests = te_tests(runs)
    if not (isinstance(shifts, list) and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in shifts)
            and len(shifts) in (0, len(tests))):
        raise InputError(f"{where}.zero_shift_arcmin: expected a list of {len(tests)} numbers (one per test), got {shifts!r}")
    for test in tests:
        ways = sorted(r.direction for r in runs if (r.torque_Nm, r.speed_rpm, r.temperature_C) == test)
        if ways != [-1, 1]:
            raise InputError(f"{where}: the test at {test[0]:g} N·m, {test[1]:g} rpm needs one forward and one "
                             f"backward run, got {len(ways)} run(s)")
    return TEExport(sample_rate_Hz=_num(table, "sample_rate_Hz", where, positive=True, required=True),
                    zero_shift_arcmin=tuple(float(v) for v in shifts))
