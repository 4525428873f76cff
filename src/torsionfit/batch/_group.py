"""The work of one shape group, wherever it runs (this process or a Dask worker): set up every
unit's problem, MAP + Laplace for all of them together, then each unit's posterior, metrics,
decision and files. A unit that fails gets an error row; the others go on."""

from ..fit import fit_map
from ._map_batch import fit_map_batch
from ._options import BatchOptions
from ._shape import shape_key
from ._unit import UnitTask, error_row, finish_unit, prepare_unit, write_row


def _map_each(problems, names, options: BatchOptions) -> list:
    """MAP of every problem together; if that fails as a whole, one at a time (so a unit that
    breaks the batched solve costs only itself)."""
    kwargs = {"n_starts": options.fit.n_starts}
    try:
        return fit_map_batch(problems, names, [options.seed] * len(problems), **kwargs)
    except Exception:  # noqa: BLE001 — fall back to the one-unit path, unit by unit
        out = []
        for problem, run_names in zip(problems, names):
            try:
                out.append(fit_map(problem, run_names, seed=options.seed, **kwargs))
            except Exception as err:  # noqa: BLE001
                out.append(err)
        return out


def fit_group(tasks: list[UnitTask], options: BatchOptions) -> list[dict]:
    """Rows of ``tasks`` (units of one shape), in order; each unit's files and row file written."""
    rows: list[dict | None] = [None] * len(tasks)
    prepared = {}
    for i, task in enumerate(tasks):
        try:
            prepared[i] = prepare_unit(task, options)
        except Exception as err:  # noqa: BLE001 — one unit must not stop the batch
            rows[i] = error_row(task, err, options)
    keys = {i: shape_key(p[3]) for i, p in prepared.items()}
    for key in dict.fromkeys(keys.values()):  # normally one shape; more if a file changed meanwhile
        idx = [i for i in prepared if keys[i] == key]
        maps = _map_each([prepared[i][3] for i in idx], [[r.name for r in prepared[i][1].runs] for i in idx], options)
        for i, map_result in zip(idx, maps):
            try:
                if isinstance(map_result, Exception):
                    raise map_result
                rows[i] = finish_unit(tasks[i], prepared[i], map_result, options, key)
            except Exception as err:  # noqa: BLE001
                rows[i] = error_row(tasks[i], err, options)
    for task, row in zip(tasks, rows):
        write_row(task, row, options)
    return rows
