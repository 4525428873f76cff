"""Many units: every ``campaign.toml`` under a folder decided against one spec, one row per unit
in ``accept_batch.csv`` and ``accept_batch.json``. A unit that cannot be read or fitted gets
``decision = "error"`` and its message in its row; the batch goes on."""

import csv
import json
from pathlib import Path

from .._x64 import in_float64
from .._errors import InputError, error_line
from ..io import load_campaign
from ..io._manifest import MANIFEST_NAME
from ..report import FitOptions
from ._decision import ACCEPT, EXIT_CODE, INDETERMINATE, REJECT
from ._unit import accept_campaign, write_accept

ERROR = "error"
#: exit code of a batch with a unit in error (the CLI's bad-input code)
EXIT_UNIT_ERROR = 2
_COLUMNS = ("unit", "decision", "p_conform", "consumer_risk", "producer_risk", "reason", "label", "campaign")


def find_campaigns(folder) -> list[Path]:
    """Every ``campaign.toml`` under ``folder`` (recursively), sorted."""
    return sorted(Path(folder).rglob(MANIFEST_NAME))


def _unit_row(manifest: Path, folder: Path, spec, options, seed, out_dir, figures, command) -> dict:
    unit = str(manifest.parent.relative_to(folder)) if manifest.parent != folder else "."
    row = {"unit": unit, "campaign": str(manifest)}
    try:
        result = accept_campaign(load_campaign(manifest), spec, options, seed=seed)
        doc = write_accept(result, Path(out_dir) / unit, figures=figures, command=command)
    except Exception as err:  # noqa: BLE001 — a production batch must not die on one unit
        return {**row, "decision": ERROR, "reason": error_line(err)}
    row.update({k: doc[k] for k in ("decision", "p_conform", "consumer_risk", "producer_risk", "risk_is_upper_bound",
                                     "reason", "label")})
    row.update({f"p_conform[{r['name']}]": r["p_conform"] for r in doc["requirements"]})
    return row


@in_float64
def accept_folder(folder, spec, out_dir, options: FitOptions = FitOptions(), seed: int = 0,
                  progress=None, figures: bool = True, command: str | None = None) -> list[dict]:
    """Decide every campaign under ``folder``; each unit's ``accept.json`` goes to
    ``out_dir/<unit folder>/``; returns one row per unit. ``progress(text)`` is told each unit;
    ``command`` is recorded in each ``accept.json``. InputError when ``folder`` holds no campaign."""
    folder = Path(folder)
    manifests = find_campaigns(folder)
    if not manifests:
        raise InputError(f"{folder}: no {MANIFEST_NAME} found in this folder or below")
    rows = []
    for i, manifest in enumerate(manifests):
        if progress is not None:
            progress(f"{i + 1}/{len(manifests)} {manifest}: fitting")
        rows.append(_unit_row(manifest, folder, spec, options, seed, out_dir, figures, command))
        if progress is not None:
            progress(f"{i + 1}/{len(manifests)} {rows[-1]['unit']}: {rows[-1]['decision']}")
    return rows


def write_batch_table(rows: list[dict], out_dir, name: str = "accept_batch",
                      columns: tuple[str, ...] = _COLUMNS, provenance: dict | None = None) -> tuple[Path, Path]:
    """``out_dir/<name>.csv`` and ``.json`` (the same rows; ``columns`` first, then every other
    key sorted; the JSON also holds ``provenance`` when given); returns both paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    extra = sorted({k for row in rows for k in row} - set(columns))
    columns = list(columns) + extra
    csv_path, json_path = out / f"{name}.csv", out / f"{name}.json"
    with open(csv_path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        writer.writerows({k: ("" if row.get(k) is None else row.get(k)) for k in columns} for row in rows)
    json_path.write_text(json.dumps({"units": rows} | ({"provenance": provenance} if provenance else {}), indent=2))
    return csv_path, json_path


def batch_exit_code(rows: list[dict]) -> int:
    """2 if any unit is in error, else 4 if any is indeterminate, else 3 if any is rejected,
    else 0 (every unit accepted)."""
    decisions = {row["decision"] for row in rows}
    if ERROR in decisions:
        return EXIT_UNIT_ERROR
    for decision in (INDETERMINATE, REJECT):
        if decision in decisions:
            return EXIT_CODE[decision]
    return EXIT_CODE[ACCEPT]
