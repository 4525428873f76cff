"""Every campaign under a folder: units in packets of consecutive units, the units of one
shape in a packet fitted together (here, in worker processes or on Dask workers), one row per
unit in ``OUT/batch.csv`` and ``OUT/batch.json``."""

from functools import partial
from pathlib import Path

from .._errors import InputError
from ..accept import EXIT_CODE, batch_exit_code, find_campaigns, write_batch_table
from ..io._manifest import MANIFEST_NAME
from ._executor import executor
from ._group import fit_group
from ._options import EMCEE, BatchOptions
from ._unit import ERROR, UnitTask, stored_row

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


def packets(tasks: list[UnitTask], options: BatchOptions, workers: int = 1) -> list[list[UnitTask]]:
    """The units in packets of consecutive units, one packet per call of ``fit_group``: the emcee
    units apart from the others and first (a packet's emcee units are sampled together), at most
    ``options.group_size`` per packet, and as many packets of a kind as a multiple of
    ``workers`` (when there are units enough), so that the workers get equal shares. Sizes
    within a kind differ by at most one."""
    out = []
    # the emcee packets first: the longest tasks first keep the workers busy to the end
    for sampler in sorted(set(options.sampler_of(t.unit) for t in tasks), key=lambda s: s != EMCEE):
        kind = [t for t in tasks if options.sampler_of(t.unit) == sampler]
        n = -(-len(kind) // options.group_size)
        n = min(-(-n // workers) * workers, len(kind))  # a multiple of the workers: they finish together
        size, extra = divmod(len(kind), n)
        start = 0
        for i in range(n):
            stop = start + size + (i < extra)
            out.append(kind[start:stop])
            start = stop
    return out


def run_batch(folder, out_dir, options: BatchOptions = BatchOptions(), scheduler: str | None = None,
              force: bool = False, progress=None, workers: int = 1) -> list[dict]:
    """Analyse every unit under ``folder`` into ``out_dir``; returns one row per unit (sorted by
    unit) and writes ``batch.csv`` / ``batch.json``. Units complete from an earlier run with
    the same settings are kept unless ``force``. The packets (:func:`packets`) run here, in
    ``workers`` processes of this machine, or on the Dask cluster at ``scheduler``; each sets up
    its units and fits those of one shape together. ``progress(text)`` is told what happens."""
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
    workers = 1 if scheduler else workers  # a Dask cluster's workers are its own
    work = packets(todo, options, workers)
    workers = max(1, min(workers, len(work)))  # no idle processes
    where = f"on the Dask cluster at {scheduler}" if scheduler else \
        f"in {workers} worker processes" if workers > 1 else "in this process"
    say(f"{len(work)} packets of up to {options.group_size} units, {where}")
    with executor(scheduler, workers=workers) as run_map:
        results = run_map(partial(fit_group, options=options), work)
        for n, (packet, packet_rows) in enumerate(zip(work, results), start=1):
            rows.update({t.unit: r for t, r in zip(packet, packet_rows)})
            failed = sum(r["status"] == ERROR for r in packet_rows)
            say(f"packet {n}/{len(work)}: {len(packet)} units done" + (f", {failed} in error" if failed else ""))
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
