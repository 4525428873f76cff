"""Every campaign under a folder: units grouped by problem shape, each group fitted together
(here or on Dask workers), one row per unit in ``OUT/batch.csv`` and ``OUT/batch.json``."""

from functools import partial
from pathlib import Path

from .._errors import InputError
from ..accept import EXIT_CODE, batch_exit_code, find_campaigns, write_batch_table
from ..io._manifest import MANIFEST_NAME
from ._executor import executor
from ._group import fit_group
from ._options import BatchOptions
from ._shape import group_by_shape
from ._unit import ERROR, UnitTask, stored_row, unit_shape, write_row

TABLE_NAME = "batch"
COLUMNS = ("unit", "status", "decision", "p_conform", "sampler", "converged", "map_converged", "reason", "shape",
           "campaign", "label")


def unit_tasks(folder, out_dir) -> list[UnitTask]:
    """One task per ``campaign.toml`` under ``folder``; InputError when there is none."""
    folder = Path(folder)
    manifests = find_campaigns(folder)
    if not manifests:
        raise InputError(f"{folder}: no {MANIFEST_NAME} found in this folder or below")
    tasks = []
    for manifest in manifests:
        unit = manifest.parent.relative_to(folder).as_posix() if manifest.parent != folder else "."
        tasks.append(UnitTask(unit=unit, manifest=manifest, out_dir=Path(out_dir) / unit))
    return tasks


def run_batch(folder, out_dir, options: BatchOptions = BatchOptions(), scheduler: str | None = None,
              force: bool = False, progress=None) -> list[dict]:
    """Analyse every unit under ``folder`` into ``out_dir``; returns one row per unit (sorted by
    unit) and writes ``batch.csv`` / ``batch.json``. Units complete from an earlier run with
    the same settings are kept unless ``force``. ``progress(text)`` is told what happens."""
    say = progress or (lambda text: None)
    tasks = unit_tasks(folder, out_dir)
    rows: dict[str, dict] = {}
    todo = []
    for task in tasks:
        row = None if force else stored_row(task, options)
        if row is None:
            todo.append(task)
        else:
            rows[task.unit] = row
    say(f"{len(tasks)} units: {len(rows)} already done, {len(todo)} to do")
    with executor(scheduler) as run_map:
        shapes = list(run_map(partial(unit_shape, options=options), todo))
        for task, (_, err_row) in zip(todo, shapes):
            if err_row is not None:  # a unit in error is told in its folder too
                rows[task.unit] = err_row
                write_row(task, err_row, options)
        # emcee units apart from the others: a group's emcee units are sampled together
        keys = [k and f"{k}:{options.sampler_of(t.unit)}" for t, (k, _) in zip(todo, shapes)]
        groups = [[todo[i] for i in g] for g in group_by_shape(keys, options.group_size)]
        say(f"{len(groups)} groups of up to {options.group_size} units of one shape")
        results = run_map(partial(fit_group, options=options), groups)
        for n, (group, group_rows) in enumerate(zip(groups, results), start=1):
            rows.update({t.unit: r for t, r in zip(group, group_rows)})
            failed = sum(r["status"] == ERROR for r in group_rows)
            say(f"group {n}/{len(groups)}: {len(group)} units done" + (f", {failed} in error" if failed else ""))
    ordered = [rows[t.unit] for t in tasks]
    write_batch_table(ordered, out_dir, name=TABLE_NAME, columns=tuple(c for c in COLUMNS if any(c in r for r in ordered)))
    return ordered


def exit_code(rows: list[dict], with_spec: bool) -> int:
    """2 if any unit is in error; with a spec, else 4 / 3 / 0 as ``torsionfit accept`` over a
    folder; without one, else 4 if any posterior did not converge, else 0."""
    if any(r["status"] == ERROR for r in rows):
        return 2
    if with_spec:
        return batch_exit_code(rows)
    return EXIT_CODE["indeterminate"] if not all(r.get("converged") for r in rows) else 0
