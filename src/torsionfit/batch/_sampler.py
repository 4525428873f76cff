"""emcee for many units of one shape at once: every unit's ``run_sampler`` (its moves, seed and
stopping rule unchanged) runs in its own thread, and the half-ensembles they ask to evaluate
are gathered into one call of a jitted vmap(units)∘vmap(walkers) log-density.

Each sampler hands its (walkers/2, dim) chunk to a shared :class:`UnitBatcher` and waits; when
every still-running unit has handed one in, the last one to arrive makes the call for all and
each gets its slice. Should that shared call fail, every waiting unit's chunk is evaluated by
itself, so that only a unit whose own call fails gets the error. A unit that has stopped
(converged, at ``max_steps`` or failed) leaves the batcher. The call stacks the running units
only, padded with copies up to a power of two (or the group's size): a stopped unit's lane is
not computed on, yet a group of K compiles at most ⌈log₂ K⌉ + 1 shapes. (Padding to the full
group instead cost 1.25–1.57× the time of one unit after another when half the units stopped
halfway: a lane costs the same whether used or not.) Every unit follows exactly the chain it
would alone: the same proposals from its own random state, the same log-density values (to
rounding), the same stopping rule.
"""

import math
import threading

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._x64 import in_float64
from ..sample import run_sampler
from ..sample._emcee import _log_density_one, batch_log_density
from ._shape import stack_problems

#: log-density of (units, n, dim) → (units, n) for a stacked problem; compiled once per shape,
#: unit count and chunk size
units_log_density = eqx.filter_jit(eqx.filter_vmap(eqx.filter_vmap(_log_density_one, in_axes=(None, 0))))


class UnitBatcher:
    """Gathers one chunk per running unit, evaluates them in one call, hands back the slices.
    ``evaluator(i)`` is unit i's ``evaluate`` for ``run_sampler``; ``leave(i)`` when it stops."""

    def __init__(self, problems: list):
        self.problems = list(problems)
        self.running = set(range(len(problems)))
        self.waiting: dict[int, np.ndarray] = {}
        self.done: dict[int, object] = {}  # unit → its log-densities, or the call's exception
        self.calls = 0
        self._stacked: tuple = ((), None)  # (lanes, their stacked problem) of the last call
        self._cond = threading.Condition()

    def evaluator(self, unit: int):
        return lambda chunk: self.evaluate(unit, chunk)

    def evaluate(self, unit: int, chunk) -> np.ndarray:
        """Log-densities of ``chunk`` (n, dim) of ``unit``, once every running unit has a chunk in."""
        with self._cond:
            self.waiting[unit] = np.asarray(chunk, dtype=float)
            self._call_if_complete()
            while unit not in self.done:
                self._cond.wait()
            out = self.done.pop(unit)
        if isinstance(out, BaseException):
            raise out
        return out

    def leave(self, unit: int) -> None:
        """``unit`` asks for nothing more; the others no longer wait for it."""
        with self._cond:
            self.running.discard(unit)
            self._call_if_complete()

    def _call_if_complete(self) -> None:
        # called with the lock held: every other running unit is waiting, nothing to overlap
        if not self.waiting or not self.running <= set(self.waiting):
            return
        units = sorted(self.waiting)
        lanes = tuple(units + units[:1] * (_lane_count(len(units), len(self.problems)) - len(units)))
        try:
            lp = np.asarray(units_log_density(self._stack(lanes), jnp.asarray(np.stack([self.waiting[i] for i in lanes]))),
                            dtype=float)
            results = {i: lp[k] for k, i in enumerate(units)}
        except Exception:  # noqa: BLE001 — the shared call failed: each unit alone, so only a
            results = {i: self._alone(i) for i in units}  # unit whose own call fails gets an error
        self.calls += 1
        self.waiting.clear()
        self.done.update(results)
        self._cond.notify_all()

    def _alone(self, unit: int):
        """Unit's waiting chunk evaluated by itself (as ``run_sampler`` alone would), or the
        exception that raises."""
        try:
            return np.asarray(batch_log_density(self.problems[unit], jnp.asarray(self.waiting[unit])), dtype=float)
        except Exception as err:  # noqa: BLE001 — that unit's result
            return err

    def _stack(self, lanes: tuple):
        """The stacked problem of ``lanes`` (unit indices), restacked only when they change."""
        if self._stacked[0] != lanes:
            self._stacked = (lanes, stack_problems([self.problems[i] for i in lanes]))
        return self._stacked[1]


def _lane_count(running: int, group: int) -> int:
    """Lanes of a call: the next power of two of the running units, at most the group's size."""
    return min(group, 2 ** math.ceil(math.log2(running)))


@in_float64
def _sample_one(batcher: UnitBatcher, unit: int, problem, map_result, kwargs: dict, out: list) -> None:
    try:
        out[unit] = run_sampler(problem, map_result, evaluate=batcher.evaluator(unit), **kwargs)
    except Exception as err:  # noqa: BLE001 — one unit's failure is its own result
        out[unit] = err
    finally:
        batcher.leave(unit)


@in_float64
def run_samplers(problems: list, map_results: list, kwargs: list[dict]) -> list:
    """``run_sampler(problems[i], map_results[i], **kwargs[i])`` for every unit (all of one
    shape and walker count), advanced together; one ``SampleResult`` — or the exception that
    unit raised — per unit. One unit runs directly, without threads."""
    if len(problems) == 1:
        try:
            return [run_sampler(problems[0], map_results[0], **kwargs[0])]
        except Exception as err:  # noqa: BLE001
            return [err]
    batcher = UnitBatcher(problems)
    out: list = [None] * len(problems)
    threads = [threading.Thread(target=_sample_one, args=(batcher, i, p, m, k, out), daemon=True,
                                name=f"emcee-unit-{i}")
               for i, (p, m, k) in enumerate(zip(problems, map_results, kwargs))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return out
