"""Many units (issue 7): every campaign under a folder fitted, measured and (with a spec)
decided; units of one problem shape fitted together (one compilation per shape and process;
MAP one unit after another on a CPU, ``vmap`` over units × starts on an accelerator; the
emcee units' ensembles advanced together), here, in worker processes or on a Dask cluster;
one row per unit."""

from ._batch import (COLUMNS as COLUMNS, WorkerProcessError as WorkerProcessError, exit_code as exit_code,
                     packets as packets, run_batch as run_batch, unit_tasks as unit_tasks)
from ._executor import default_workers as default_workers, executor as executor, local_map as local_map, usable_cpus as usable_cpus
from ._group import fit_group as fit_group
from ._map_batch import fit_map_batch as fit_map_batch
from ._sampler import UnitBatcher as UnitBatcher, run_samplers as run_samplers
from ._options import BatchOptions as BatchOptions, posterior_sample as posterior_sample
from ._shape import group_by_shape as group_by_shape, shape_key as shape_key, stack_problems as stack_problems
from ._unit import (
    DONE as DONE,
    ERROR as ERROR,
    ROW_FILE as ROW_FILE,
    UnitTask as UnitTask,
    stored_row as stored_row,
)
