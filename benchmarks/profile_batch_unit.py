"""Where one unit's time goes in ``torsionfit batch`` (Laplace sampler, one process, one BLAS thread
as the commands): SYNTHETIC 10 001-sample units of ``benches/full_fit_10k.toml``; a first group
compiles, a second group of the same shape is timed warm, stage by stage, with the XLA
compilations counted per stage (a stage that compiles in the warm group compiles per unit, not
per shape).

    .venv/bin/python benchmarks/profile_batch_unit.py [--units 3] [--group-size 3]
"""

import argparse
import sys
import tempfile
import time
from collections import defaultdict
from contextlib import contextmanager
from pathlib import Path

import jax

HERE = Path(__file__).resolve().parent
BENCH = HERE / "benches" / "full_fit_10k.toml"


class Stages:
    """Wall time and XLA compilations per named stage."""

    def __init__(self):
        self.seconds = defaultdict(float)
        self.compiles = defaultdict(int)
        self.current = None
        jax.monitoring.register_event_duration_secs_listener(self._listen)

    def _listen(self, event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration" and self.current is not None:
            self.compiles[self.current] += 1

    @contextmanager
    def stage(self, name):
        outer, self.current = self.current, name
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] += time.perf_counter() - t0
            self.current = outer


def _wrap(stages, module, attr, name):
    """Time ``module.attr`` as stage ``name`` wherever the batch calls it."""
    fn = getattr(module, attr)

    def timed(*args, **kwargs):
        with stages.stage(name):
            return fn(*args, **kwargs)

    setattr(module, attr, timed)


def _instrument(stages):
    from torsionfit.batch import _group, _unit
    from torsionfit.report import _pipeline

    _wrap(stages, _unit, "load_campaign", "load campaign")
    _wrap(stages, _unit, "prepare_fit", "prepare (decimate, build problem)")
    _wrap(stages, _group, "fit_map_batch", "MAP + Laplace (fit_map_batch)")
    _wrap(stages, _pipeline, "_values_over_draws", "parameter values of metric draws")
    _wrap(stages, _pipeline, "derived_metrics_for", "derived metrics: set-up")
    _wrap(stages, _pipeline, "_residuals", "RMSE residuals")
    _wrap(stages, _unit, "write_fit", "write fit.json")
    _wrap(stages, _unit, "write_row", "write row")
    _wrap(stages, _unit, "finish_fit", "finish_fit (all after MAP)")
    _wrap(stages, _group, "group_by_shape", "group by shape")
    from torsionfit.report._derived import DerivedMetrics

    over = DerivedMetrics.over_draws

    def timed_over(self, values):
        with stages.stage("derived metrics: over draws"):
            return jax.block_until_ready(over(self, values))

    DerivedMetrics.over_draws = timed_over


def main(argv=None) -> int:
    from torsionfit._threads import single_blas_thread

    with single_blas_thread():  # as the commands run
        return _main(argv)


def _main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--units", type=int, default=3, help="units in the timed (warm) group")
    args = parser.parse_args(argv)
    from torsionfit.batch import BatchOptions, run_batch
    from torsionfit.bench import load_bench, simulate
    from torsionfit.io import write_campaign
    from torsionfit.report import FitOptions

    work = Path(tempfile.mkdtemp(prefix="profile_batch_"))
    bench = load_bench(BENCH)
    for folder, seeds in (("warm-up", range(1, args.units + 1)), ("timed", range(101, 101 + args.units))):
        for seed in seeds:
            write_campaign(simulate(bench, seed=seed).campaign, work / folder / f"unit-{seed:04d}", label=bench.label)
    options = BatchOptions(fit=FitOptions(sampler="laplace", progress=False), group_size=args.units)
    t0 = time.perf_counter()
    run_batch(work / "warm-up", work / "out-warm-up", options)
    cold = time.perf_counter() - t0
    stages = Stages()
    _instrument(stages)
    with stages.stage("whole batch"):
        run_batch(work / "timed", work / "out-timed", options)
    total = stages.seconds["whole batch"]
    print(f"cold group of {args.units} units (compilation included): {cold:.1f} s")
    print(f"warm group of {args.units} units: {total:.2f} s, {total / args.units:.2f} s per unit")
    print(f"{'stage':40s} {'s per unit':>10s} {'XLA compiles':>13s}")
    for name, sec in stages.seconds.items():
        print(f"{name:40s} {sec / args.units:10.3f} {stages.compiles[name]:13d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
