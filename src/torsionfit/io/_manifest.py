"""The campaign manifest (``campaign.toml``, DESIGN §5.1): reading it with its run files into
a :class:`Campaign`, and writing a campaign back as manifest + CSV files.

Every key is checked: an unknown key is an error (a typo such as ``rated_torqe_Nm`` must not
be silently ignored), and every message is one line naming the file, the key or column, and
what was expected. Runs are named ``runs[i] 'name'``, ``i`` counted from 0 in the order of
the ``[[runs]]`` tables.
"""

import difflib
import json
import math
import os
import re
import tomllib
from pathlib import Path

import numpy as np

from .. import units
from .._errors import InputError
from ._campaign import Campaign, HysteresisRun, Instrument, Reducer, TransmissionErrorRun
from ._columns import CANONICAL, check_unit
from ._convention import check_te_convention
from ._runs import PEAK_FROM_DATA, RunSpec, read_run
from ._te_twist import check_te_twist
from ._te_zeros import check_te_zero_groups

MANIFEST_NAME = "campaign.toml"
KINDS = ("hysteresis", "transmission_error")
DIRECTIONS = {"forward": 1, "backward": -1}
TE_CONVENTIONS = ("lag_positive", "lag_negative")

_TOP_KEYS = ("label", "reducer", "instrument", "runs")
_REDUCER_KEYS = ("name", "rated_torque_Nm", "ratio", "max_speed_rpm")
_INSTRUMENT_KEYS = (
    "torque_full_scale_Nm",
    "torque_accuracy_pct_fs",
    "encoder_resolution_arcsec",
    "sample_rate_Hz",
    "input_encoder_resolution_arcsec",
)
_COMMON_RUN_KEYS = ("name", "kind", "file", "columns", "units", "select", "temperature_C")
_RUN_KEYS = {
    "hysteresis": _COMMON_RUN_KEYS + ("loading_rate_Nm_per_s", "peak_torque_Nm", "angle_sign", "torque_sign",
                   "condition"),
    "transmission_error": _COMMON_RUN_KEYS
    + ("speed_rpm", "input_speed_rpm", "torque_Nm", "direction", "te_convention", "zero_group"),
}


# ----------------------------------------------------------------------------- reading


def load_campaign(path) -> Campaign:
    """Read a campaign manifest and all its run files.

    ``path`` is the manifest (``campaign.toml``) or a folder holding one. Run files are
    CSV or gzip-compressed CSV (``.csv.gz``), found relative to the manifest. Columns
    carry their unit in their name (``torque_Nm``, ``angle_arcmin``, ...) unless the run
    maps them with ``[runs.columns]``; a mapped column is in the unit given by
    ``[runs.units]``, or in SI (rad, Nm, s) when none is given. Arrays of the returned
    campaign are in SI: rad, N·m, s (°C for temperature). The manifest's top-level
    ``label`` goes to ``Campaign.notes``.

    Raises :class:`~torsionfit.InputError` (one line naming file, key or column) on bad input.
    """
    manifest = Path(path)
    if manifest.is_dir():
        manifest = manifest / MANIFEST_NAME
    shown = str(manifest)
    doc = _read_toml(manifest, "campaign manifest")
    _check_keys(doc, _TOP_KEYS, shown, "the top level")
    label = doc.get("label", "")
    if not isinstance(label, str):
        raise InputError(f"{shown}: label must be a string, got {label!r}")
    reducer = _reducer(_table(doc, "reducer", shown, required=True), manifest, shown)
    instrument = _instrument(_table(doc, "instrument", shown, required=False), shown)

    entries = doc.get("runs", [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise InputError(f"{shown}: runs must be an array of tables, written as [[runs]]")
    if not entries:
        raise InputError(
            f"{shown}: the campaign has no runs; add at least one [[runs]] table "
            f"with name, kind and file"
        )
    folder = manifest.resolve().parent
    specs = [_run_spec(i, entry, folder, shown, reducer, instrument) for i, entry in enumerate(entries)]
    first_use: dict[str, int] = {}
    for spec in specs:
        if spec.name in first_use:
            raise InputError(
                f"{shown}: runs[{spec.index}] name {spec.name!r} is already used by "
                f"runs[{first_use[spec.name]}]; run names must be unique"
            )
        first_use[spec.name] = spec.index

    runs = tuple(
        read_run(spec, reducer, f"{shown}: runs[{spec.index}] {spec.name!r} file {spec.file}")
        for spec in specs
    )
    check_te_convention(runs, shown)
    check_te_twist(runs, reducer.rated_torque_Nm, shown)
    check_te_zero_groups(runs, shown)
    return Campaign(reducer, instrument, runs, path=manifest.resolve(), notes=label)


def _read_toml(path: Path, what: str) -> dict:
    """The TOML document at ``path``; InputError naming the file if it is missing or unreadable
    (``what`` names the kind of file, e.g. "campaign manifest")."""
    if not path.is_file():
        raise InputError(f"{path}: {what} not found")
    try:
        with open(path, "rb") as handle:
            return tomllib.load(handle)
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"{path}: TOML syntax error: {err}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: cannot read the {what} ({err})") from None


def _check_keys(table: dict, allowed, where: str, section: str) -> None:
    """InputError for the first key of ``table`` not in ``allowed``, with a suggestion."""
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise InputError(
                f"{where}: unknown key {key!r} in {section}{hint}; "
                f"expected one of {', '.join(allowed)}"
            )


def _table(doc: dict, key: str, where: str, *, required: bool, section: str = "") -> dict:
    """``doc[key]`` as a table ({} if absent); ``section`` is its TOML header for messages."""
    section = section or f"[{key}]"
    if key not in doc:
        if required:
            raise InputError(f"{where}: missing {section} table")
        return {}
    if not isinstance(doc[key], dict):
        raise InputError(f"{where}: {key} must be a table, written as {section}")
    return doc[key]


def _number(table: dict, key: str, where: str, *, required=False, minimum=None, positive=False):
    """``table[key]`` as a float (None if absent and not required), range-checked."""
    if key not in table:
        if required:
            raise InputError(f"{where}: missing required key {key!r}")
        return None
    value = table[key]
    # bool is an int in Python; `true` is never a meaningful number here.
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where}: {key} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise InputError(f"{where}: {key} must be > 0, got {value!r}")
    if minimum is not None and value < minimum:
        raise InputError(f"{where}: {key} must be >= {minimum}, got {value!r}")
    return float(value)


def _peak(table: dict, where: str) -> float | str | None:
    """``peak_torque_Nm``: a number > 0 (N·m), or ``"data"`` (:data:`PEAK_FROM_DATA`)."""
    if table.get("peak_torque_Nm") == PEAK_FROM_DATA:
        return PEAK_FROM_DATA
    if isinstance(table.get("peak_torque_Nm"), str):
        raise InputError(f"{where}: peak_torque_Nm must be a number > 0 (N·m) or \"{PEAK_FROM_DATA}\" (the run's own "
                         f"peak, read off its torque), got {table['peak_torque_Nm']!r}")
    return _number(table, "peak_torque_Nm", where, positive=True)


def _text(table: dict, key: str, where: str, *, required=False, default=None) -> str | None:
    if key not in table:
        if required:
            raise InputError(f"{where}: missing required key {key!r}")
        return default
    value = table[key]
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"{where}: {key} must be a non-empty string, got {value!r}")
    return value


def _reducer(table: dict, manifest: Path, shown: str) -> Reducer:
    where = f"{shown}: [reducer]"
    _check_keys(table, _REDUCER_KEYS, shown, "[reducer]")
    return Reducer(
        # Without a name the manifest's own name identifies the unit.
        name=_text(table, "name", where, default=manifest.stem),
        # Optional: data-only metrics read their torque scale from the data without it; the
        # fit, accept and paper entry points say they need it (fit.check_fittable).
        rated_torque_Nm=_number(table, "rated_torque_Nm", where, positive=True),
        ratio=_number(table, "ratio", where, positive=True),
        max_speed_rpm=_number(table, "max_speed_rpm", where, positive=True),
    )


def _instrument(table: dict, shown: str) -> Instrument:
    where = f"{shown}: [instrument]"
    _check_keys(table, _INSTRUMENT_KEYS + ("te_convention",), shown, "[instrument]")
    values = {key: _number(table, key, where, positive=True) for key in _INSTRUMENT_KEYS}
    return Instrument(**values, te_convention=_convention(table, where, "lag_positive"))


def _convention(table: dict, where: str, default: str) -> str:
    value = _text(table, "te_convention", where, default=default)
    if value not in TE_CONVENTIONS:
        raise InputError(
            f"{where}: te_convention must be 'lag_positive' (a load that makes the output lag "
            f"gives positive TE) or 'lag_negative', got {value!r}"
        )
    return value


def _run_spec(index: int, entry: dict, folder: Path, shown: str, reducer: Reducer,
              instrument: Instrument) -> RunSpec:
    where = f"{shown}: runs[{index}]"
    name = _text(entry, "name", where, required=True)
    where = f"{where} {name!r}"
    kind = _text(entry, "kind", where, required=True)
    if kind not in KINDS:
        raise InputError(
            f"{where}: unknown kind {kind!r}; expected 'hysteresis' or 'transmission_error'"
        )
    _check_keys(entry, _RUN_KEYS[kind], where, f"a {kind} run")
    file = _text(entry, "file", where, required=True)
    columns = _column_map(entry, kind, where)
    unit_names = _unit_map(entry, kind, columns, where)
    select = _select(entry, where)
    common = dict(
        index=index,
        name=name,
        kind=kind,
        file=file,
        path=(folder / file).resolve(),
        columns=columns,
        units=unit_names,
        select=select,
        temperature_C=_number(entry, "temperature_C", where),
        encoder_resolution_arcsec=instrument.encoder_resolution_arcsec,
        input_encoder_resolution_arcsec=instrument.input_encoder_resolution_arcsec,
        sample_rate_Hz=instrument.sample_rate_Hz,
    )
    if kind == "hysteresis":
        return RunSpec(
            **common,
            condition=_select(entry, where, "condition"),
            loading_rate_Nm_per_s=_number(entry, "loading_rate_Nm_per_s", where, positive=True),
            peak_torque_Nm=_peak(entry, where),
            angle_sign=_sign(entry, where, "angle_sign", "positive torque gives a larger angle", "angle"),
            torque_sign=_sign(entry, where, "torque_sign", "positive torque twists the output forward", "torque"),
        )
    direction = _text(entry, "direction", where, required=True)
    if direction not in DIRECTIONS:
        raise InputError(f"{where}: direction must be 'forward' or 'backward', got {direction!r}")
    speed = _number(entry, "speed_rpm", where, minimum=0)
    input_speed = _number(entry, "input_speed_rpm", where, minimum=0)
    if (speed is None) == (input_speed is None):
        raise InputError(
            f"{where}: give one of speed_rpm (output speed) or input_speed_rpm (motor speed, "
            f"with [reducer] ratio); got {'both' if speed is not None else 'neither'}"
        )
    if input_speed is not None and reducer.ratio is None:
        raise InputError(
            f"{where}: input_speed_rpm needs [reducer] ratio to give the output speed; "
            f"add ratio or give speed_rpm"
        )
    return RunSpec(
        **common,
        speed_rpm=speed,
        input_speed_rpm=input_speed,
        torque_Nm=_number(entry, "torque_Nm", where, required=True, minimum=0),
        direction=DIRECTIONS[direction],
        te_convention=_convention(entry, where, instrument.te_convention),
        zero_group=_text(entry, "zero_group", where),
    )


def _sign(entry: dict, where: str, key: str, default_meaning: str, column: str) -> int:
    """``angle_sign`` / ``torque_sign``: 1 (default: positive torque twists the output forward,
    to a larger angle) or -1 (the bench counts that column the other way: negated on reading)."""
    value = entry.get(key, 1)
    if isinstance(value, bool) or value not in (1, -1):
        raise InputError(f"{where}: {key} must be 1 ({default_meaning}) or -1 (the bench counts the {column} the "
                         f"other way: the column is negated on reading), got {value!r}")
    return int(value)


def _canonical_table(entry: dict, key: str, kind: str, where: str) -> dict[str, str]:
    """``[runs.<key>]``: a table from canonical column names to non-empty strings."""
    table = _table(entry, key, where, required=False, section=f"[runs.{key}]")
    _check_keys(table, tuple(CANONICAL[kind]), where, f"[runs.{key}] of a {kind} run")
    for name, value in table.items():
        if not isinstance(value, str) or not value.strip():
            raise InputError(
                f"{where}: [runs.{key}] {name} must be a non-empty string, got {value!r}"
            )
    return dict(table)


def _column_map(entry: dict, kind: str, where: str) -> dict[str, str]:
    return _canonical_table(entry, "columns", kind, where)


def _unit_map(entry: dict, kind: str, columns: dict[str, str], where: str) -> dict[str, str]:
    unit_names = _canonical_table(entry, "units", kind, where)
    for name, unit in unit_names.items():
        if name not in columns:
            # A suffixed column already carries its unit; two sources of truth would clash.
            raise InputError(
                f"{where}: [runs.units] {name} has no [runs.columns] {name} entry; units are "
                f"only given for mapped columns (default columns carry theirs, e.g. angle_deg)"
            )
        check_unit(CANONICAL[kind][name], unit, f"{where}: [runs.units] {name}")
    return unit_names


def _select(entry: dict, where: str, key: str = "select") -> dict:
    """``[runs.select]`` (or ``[runs.condition]``, ``key``): file column → list of allowed values
    or ``{min, max}``."""
    table = _table(entry, key, where, required=False, section=f"[runs.{key}]")
    for column, rule in table.items():
        at = f"{where}: [runs.{key}] {column}"
        if isinstance(rule, dict):
            _check_keys(rule, ("min", "max"), at, "a range")
            if not rule:
                raise InputError(f"{at}: a range needs min and/or max")
            for bound in rule:
                _number(rule, bound, at)
        elif isinstance(rule, list):
            numbers = [not isinstance(v, (str, bool)) and isinstance(v, (int, float)) for v in rule]
            strings = [isinstance(v, str) for v in rule]
            if not rule or not (all(numbers) or all(strings)):
                raise InputError(
                    f"{at}: expected a non-empty list of numbers or of strings, got {rule!r}"
                )
        else:
            raise InputError(
                f"{at}: expected a list of allowed values or {{min = .., max = ..}}, got {rule!r}"
            )
    return dict(table)


# ----------------------------------------------------------------------------- writing


def write_campaign(campaign: Campaign, directory, *, label=None, bench_file=None) -> Path:
    """Write ``campaign`` as ``directory/campaign.toml`` plus one CSV per run.

    Hysteresis files have columns ``time_s, torque_Nm, angle_arcmin``; TE files
    ``output_angle_deg, te_arcsec`` and, when present, ``time_s``, ``torque_Nm`` (the torque
    series) and ``temperature_C``. ``label`` (default: ``campaign.notes``) becomes the
    manifest's ``label`` and a ``# label`` first line of every CSV. ``bench_file``, the bench
    description that produced the campaign, is named in a comment of the manifest. Numbers
    are written with the shortest repr that reads back to the same float, so a round trip
    only loses the rounding of the unit conversions. Returns the manifest path.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    label = campaign.notes if label is None else str(label)
    lines = ["# Campaign manifest (torsionfit); run files are relative to this file."]
    if bench_file is not None:
        lines.append(f"# Made by the virtual bench from {_relative(bench_file, directory)}")
    if label:
        lines.append(f"label = {_toml(label)}")
    lines += ["", "[reducer]"]
    lines += _toml_pairs(
        name=campaign.reducer.name,
        rated_torque_Nm=campaign.reducer.rated_torque_Nm,
        ratio=campaign.reducer.ratio,
        max_speed_rpm=campaign.reducer.max_speed_rpm,
    )
    instrument = _toml_pairs(**{k: getattr(campaign.instrument, k) for k in _INSTRUMENT_KEYS})
    if instrument:
        lines += ["", "[instrument]"] + instrument

    used: set[str] = set()
    for run in campaign.runs:
        file = _file_name(run.name, used)
        if isinstance(run, HysteresisRun):
            keys = dict(
                loading_rate_Nm_per_s=run.loading_rate_Nm_per_s,
                peak_torque_Nm=PEAK_FROM_DATA if run.peak_from_data else run.peak_torque_Nm,
                temperature_C=run.nominal_temperature_C,
            )
            columns = {
                "time_s": run.time_s,
                "torque_Nm": run.torque_Nm,
                "angle_arcmin": units.from_si(run.angle_rad, "angle", "arcmin"),
                "temperature_C": run.temperature_C,
                # conditioning rows: a column of their own, declared by [runs.condition] below
                "conditioning": None if run.conditioning is None else np.asarray(run.conditioning, float),
            }
        elif isinstance(run, TransmissionErrorRun):
            direction = {1: "forward", -1: "backward"}[int(run.direction)]
            # TE is written lag-positive (as held in memory), so no te_convention key
            keys = dict(speed_rpm=run.speed_rpm, torque_Nm=run.torque_Nm, direction=direction,
                        zero_group=run.zero_group, temperature_C=run.nominal_temperature_C)
            columns = {
                "output_angle_deg": units.from_si(run.output_angle_rad, "angle", "deg"),
                "te_arcsec": units.from_si(run.te_rad, "angle", "arcsec"),
                "time_s": run.time_s,
                "torque_Nm": run.torque_series_Nm,
                "temperature_C": run.temperature_C,
            }
        else:
            raise TypeError(f"run {run.name!r}: not a HysteresisRun or TransmissionErrorRun")
        lines += ["", "[[runs]]"]
        lines += _toml_pairs(name=run.name, kind=run.kind, file=file, **keys)
        if isinstance(run, HysteresisRun) and run.conditioning is not None:
            lines += ["[runs.condition]", "conditioning = [1]"]
        _write_csv(directory / file, columns, label)

    manifest = directory / MANIFEST_NAME
    manifest.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return manifest


def _toml(value) -> str:
    """One TOML value. JSON string escapes are valid TOML basic-string escapes."""
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return str(int(value))
    return repr(float(value))


def _toml_pairs(**values) -> list[str]:
    return [f"{key} = {_toml(value)}" for key, value in values.items() if value is not None]


def _file_name(run_name: str, used: set[str]) -> str:
    """A safe, unique CSV name for a run (unique ignoring case, for case-blind filesystems)."""
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", run_name).strip("._") or "run"
    name, n = f"{stem}.csv", 1
    while name.lower() in used:
        n += 1
        name = f"{stem}-{n}.csv"
    used.add(name.lower())
    return name


def _write_csv(path: Path, columns: dict, label: str) -> None:
    present = {k: np.asarray(v, dtype=float).tolist() for k, v in columns.items() if v is not None}
    with open(path, "w", encoding="utf-8", newline="") as handle:
        for line in label.splitlines():
            handle.write(f"# {line}\n")
        handle.write(",".join(present) + "\n")
        # repr of a Python float is the shortest text that reads back to the same float.
        for row in zip(*present.values()):
            handle.write(",".join(map(repr, row)) + "\n")


def _relative(path, directory: Path) -> str:
    """``path`` relative to ``directory`` when it is close by (a bench file shipped with its
    campaign), else absolute: a chain of '../../..' says less than the full path."""
    path = Path(path).resolve()
    try:
        relative = os.path.relpath(path, directory.resolve())
    except ValueError:  # another drive on Windows
        return str(path)
    return str(path) if relative.startswith(os.path.join(os.pardir, os.pardir)) else relative
