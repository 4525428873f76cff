"""The work of one packet of units, wherever it runs (this process, a worker process or a Dask
worker): set up every unit's problem; for the units of each shape, MAP + Laplace together and
the emcee units' posteriors together; then each unit's metrics, decision and files. A unit
that fails gets an error row; the others go on."""

from .._x64 import in_float64
from ..fit import fit_map
from ..fit._misfit import widen_for_misfit
from ..report import sampler_kwargs
from ._map_batch import fit_map_batch
from ._options import EMCEE, BatchOptions
from ._sampler import run_samplers
from ._shape import group_by_shape, shape_key
from ._unit import UnitTask, error_row, finish_unit, prepare_unit, write_row


def _map_each(problems, names, options: BatchOptions) -> list:
    """MAP of every problem together (``fit_map_batch``); if a vmapped solve fails as a whole,
    one at a time (so a unit that breaks it costs only itself)."""
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


def _sample_each(tasks, prepared: dict, idx: list[int], maps: list, options: BatchOptions) -> dict:
    """{unit index: SampleResult or the exception} of the emcee units among ``idx`` whose MAP
    succeeded, sampled together (``run_samplers``)."""
    todo = [(i, m) for i, m in zip(idx, maps)
            if not isinstance(m, Exception) and options.sampler_of(tasks[i].unit) == EMCEE]
    if not todo:
        return {}
    kwargs = [sampler_kwargs(options.fit_options_of(tasks[i].unit), options.seed) for i, _ in todo]
    results = run_samplers([prepared[i][3] for i, _ in todo], [m for _, m in todo], kwargs)
    return {i: r for (i, _), r in zip(todo, results)}


@in_float64
def fit_group(tasks: list[UnitTask], options: BatchOptions) -> list[dict]:
    """Rows of ``tasks`` (a packet), in order; each unit's files and row file written."""
    rows: list[dict | None] = [None] * len(tasks)
    prepared = {}
    for i, task in enumerate(tasks):
        try:
            prepared[i] = prepare_unit(task, options)
        except Exception as err:  # noqa: BLE001 — one unit must not stop the batch
            rows[i] = error_row(task, err, options)
    keys = [shape_key(prepared[i][3]) if i in prepared else None for i in range(len(tasks))]
    for idx in group_by_shape(keys, options.group_size):  # normally one shape; more in a folder of mixed units
        key = keys[idx[0]]
        maps = list(_map_each([prepared[i][3] for i in idx], [[r.name for r in prepared[i][1].runs] for i in idx], options))
        for k, i in enumerate(idx):  # widened before sampling, as fit_campaign does
            if not isinstance(maps[k], Exception) and options.fit_options_of(tasks[i].unit).misfit_inflation:
                problem, maps[k] = widen_for_misfit(prepared[i][3], maps[k])
                prepared[i] = (*prepared[i][:3], problem)
        samples = _sample_each(tasks, prepared, idx, maps, options)
        for i, map_result in zip(idx, maps):
            try:
                for result in (map_result, samples.get(i)):
                    if isinstance(result, Exception):
                        raise result
                rows[i] = finish_unit(tasks[i], prepared[i], map_result, options, key, samples.get(i))
            except Exception as err:  # noqa: BLE001
                rows[i] = error_row(tasks[i], err, options)
    for task, row in zip(tasks, rows):
        write_row(task, row, options)
    return rows
