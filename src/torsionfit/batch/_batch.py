"""Every campaign under a folder: units in packets of consecutive units, the units of one
shape in a packet fitted together (here, in worker processes or on Dask workers), one row per
unit in ``OUT/batch.csv`` and ``OUT/batch.json``."""

from concurrent.futures.process import BrokenProcessPool
from functools import partial
from pathlib import Path

from .._x64 import in_float64
from .._errors import InputError
from .._provenance import provenance
from ..accept import EXIT_CODE, batch_exit_code, find_campaigns, write_batch_table
from ..io._manifest import MANIFEST_NAME
from ._executor import executor
from ._group import fit_group
from ._options import EMCEE, BatchOptions
from ._unit import ERROR, UnitTask, clear_row, error_row, stored_row, write_row, written_row

TABLE_NAME = "batch"
COLUMNS = ("unit", "status", "decision", "p_conform", "sampler", "converged", "map_converged", "reason",
           "prior_dominated", "shape", "campaign", "label")
#: units that each killed a process of their own, with no unit ever back from a worker process,
#: before the batch concludes that its worker processes cannot work at all
STARTUP_DEATHS = 3


class WorkerProcessError(RuntimeError):
    """The batch's worker processes die before any unit comes back from one (they cannot start,
    or every unit kills them); one line for the user."""


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


@in_float64
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
    for task in todo:
        clear_row(task)  # a row file found after a worker process died is then this run's
    fit = partial(fit_group, options=options)
    pending = todo
    back = False  # has any unit come back from a worker process (rows returned or written)?
    culprits = 0
    while pending:
        work = packets(pending, options, workers)
        n_workers = max(1, min(workers, len(work)))  # no idle processes
        where = f"on the Dask cluster at {scheduler}" if scheduler else \
            f"in {n_workers} worker processes" if n_workers > 1 else "in this process"
        say(f"{len(work)} packets of up to {options.group_size} units, {where}")
        lost, came = _dispatch(fit, work, rows, say, scheduler=scheduler, workers=n_workers)
        back = back or came
        if not lost:
            break
        # FIFO dispatch: the packets that were running are among the first unfinished ones
        suspects = [t for packet in lost[:n_workers + 1] for t in packet]
        say(f"a worker process died: the unit(s) it may have been fitting ({len(suspects)}) are redone one at a "
            "time in a process of their own")
        while suspects:
            again, came = _dispatch(fit, [[t] for t in suspects], rows, say, workers=1, processes=True)
            back = back or came
            if not again:
                break
            culprit = again[0][0]
            rows[culprit.unit] = error_row(culprit, RuntimeError(
                "the worker process fitting this unit died (a crash or out of memory, not an exception)"), options)
            write_row(culprit, rows[culprit.unit], options)
            culprits += 1
            if culprits >= STARTUP_DEATHS and not back:
                raise WorkerProcessError(
                    f"{culprits} units in a row each killed a worker process of their own and no unit has come back "
                    "from one: the worker processes cannot work here (run with --workers 1 to see the error in this "
                    "process); the units done so far have their rows in their folders")
            suspects = [packet[0] for packet in again[1:]]
        pending = [t for packet in lost[n_workers + 1:] for t in packet]
    ordered = [rows[t.unit] for t in tasks]
    write_batch_table(ordered, out_dir, name=TABLE_NAME, columns=tuple(c for c in COLUMNS if any(c in r for r in ordered)),
                      provenance=provenance(options.seed, options.command))
    return ordered


def _dispatch(fit, work: list[list[UnitTask]], rows: dict, say, scheduler=None, workers=1,
              processes=None) -> tuple[list, bool]:
    """Run the packets; their rows into ``rows``. Returns ([] or, when a worker process died, the
    packets whose rows are not all in — those written before it died are taken from the units'
    row files; whether any unit's row came back)."""
    done = 0
    try:
        with executor(scheduler, workers=workers, processes=processes) as run_map:
            for n, (packet, packet_rows) in enumerate(zip(work, run_map(fit, work)), start=1):
                rows.update({t.unit: r for t, r in zip(packet, packet_rows)})
                failed = sum(r["status"] == ERROR for r in packet_rows)
                say(f"packet {n}/{len(work)}: {len(packet)} units done" + (f", {failed} in error" if failed else ""))
                done = n
    except BrokenProcessPool:
        lost, came = [], done > 0
        for packet in work[done:]:
            found = {t.unit: written_row(t) for t in packet}
            came = came or any(found.values())
            if all(found.values()):
                rows.update(found)
            else:
                lost.append(packet)
        return lost, came
    return [], True


def exit_code(rows: list[dict], with_spec: bool) -> int:
    """2 if any unit is in error; with a spec, else 4 / 3 / 0 as ``torsionfit accept`` over a
    folder; without one, else 4 if any posterior did not converge, else 0."""
    if any(r["status"] == ERROR for r in rows):
        return 2
    if with_spec:
        return batch_exit_code(rows)
    return EXIT_CODE["indeterminate"] if not all(r.get("converged") for r in rows) else 0
