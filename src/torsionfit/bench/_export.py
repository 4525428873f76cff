"""A simulated TE campaign written the way a real TE bench exports it.

Such a bench (e.g. an RV-reducer TE rig) writes one CSV per test: the forward and the backward
revolution side by side (``Pos_fw;TE_fw;Pos_bw;TE_bw``), angles and TE in degrees, TE negative
when the load makes the output lag, no time column (a fixed logger clock), the motor speed in
the file name, the shorter direction padded with a NaN row, and the encoders re-zeroed before
every test. :func:`write_te_export` writes a :class:`Simulation` of a bench with ``[te_export]``
that way, with the manifest that reads it (``te_convention``, one ``zero_group`` per test,
``input_speed_rpm``, ``temperature_C``).
"""

import math
from pathlib import Path

import numpy as np

from .._errors import InputError
from ..io import TransmissionErrorRun
from ..io._manifest import MANIFEST_NAME, _toml, _toml_pairs
from ._config import Bench
from ._simulate import Simulation

#: the sign the files are written in (the manifest must declare it to read them right)
EXPORT_CONVENTION = "lag_negative"


def write_te_export(sim: Simulation, bench: Bench, directory, *, declare: bool = True) -> Path:
    """Write ``sim`` (simulated from ``bench``, which has ``[te_export]``) as a TE bench export
    in ``directory``: one side-by-side CSV per test plus ``campaign.toml``. ``declare=False``
    leaves ``te_convention`` out of the manifest, as a user who did not declare it would, so
    reading it stops with the one-line ``te_convention`` error. Returns the manifest path."""
    if bench.te_export is None:
        raise InputError(f"{bench.path or 'bench'}: no [te_export] table; the export layout needs its sample_rate_Hz")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    tests: dict[str, dict[int, TransmissionErrorRun]] = {}
    for run in sim.campaign.runs:
        if not isinstance(run, TransmissionErrorRun) or run.zero_group is None:
            raise InputError(f"run {run.name!r}: not a TE run of a [te_export] simulation")
        tests.setdefault(run.zero_group, {})[int(run.direction)] = run

    reducer, instrument = sim.campaign.reducer, sim.campaign.instrument
    lines = [f"label = {_toml(bench.label)}", "", "[reducer]"]
    lines += _toml_pairs(name=reducer.name, rated_torque_Nm=reducer.rated_torque_Nm, ratio=reducer.ratio,
                         max_speed_rpm=reducer.max_speed_rpm)
    lines += ["", "[instrument]"]
    lines += _toml_pairs(torque_full_scale_Nm=instrument.torque_full_scale_Nm,
                         torque_accuracy_pct_fs=instrument.torque_accuracy_pct_fs,
                         encoder_resolution_arcsec=instrument.encoder_resolution_arcsec,
                         sample_rate_Hz=bench.te_export.sample_rate_Hz,
                         te_convention=EXPORT_CONVENTION if declare else None)
    for stem, pair in tests.items():
        file = f"{stem}.csv"
        _write_side_by_side(directory / file, pair[1], pair[-1], bench.label)
        for way, tag in ((1, "fw"), (-1, "bw")):
            run = pair[way]
            lines += ["", "[[runs]]"]
            lines += _toml_pairs(name=f"{stem}-{tag}", kind="transmission_error", file=file,
                                 input_speed_rpm=run.speed_rpm * reducer.ratio, torque_Nm=run.torque_Nm,
                                 direction="forward" if way > 0 else "backward", zero_group=stem,
                                 temperature_C=run.nominal_temperature_C)
            lines += ["[runs.columns]", f'output_angle = "Pos_{tag}"', f'te = "TE_{tag}"',
                      "[runs.units]", 'output_angle = "deg"', 'te = "deg"']
    manifest = directory / MANIFEST_NAME
    manifest.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return manifest


def _write_side_by_side(path: Path, fw: TransmissionErrorRun, bw: TransmissionErrorRun, label: str) -> None:
    """``Pos_fw;TE_fw;Pos_bw;TE_bw`` in degrees, TE lag-negative, the shorter column pair padded
    with NaN to the longer's length."""
    n = max(len(fw), len(bw))

    def padded(values):
        out = np.full(n, math.nan)
        out[: len(values)] = values
        return out

    columns = []
    for run in (fw, bw):
        columns += [padded(np.rad2deg(run.output_angle_rad)), padded(-np.rad2deg(run.te_rad))]
    with open(path, "w", encoding="utf-8", newline="") as handle:
        for line in label.splitlines():
            handle.write(f"# {line}\n")
        handle.write("Pos_fw;TE_fw;Pos_bw;TE_bw\n")
        for row in zip(*columns):
            handle.write(";".join("NaN" if math.isnan(v) else repr(float(v)) for v in row) + "\n")
