"""torsionfit batch (issue 7): a folder of SYNTHETIC units (tests/benches/rv_small_base.toml,
decimated ×4 to keep the fits short) with bad units among them; vmapped MAP against the one-unit
``fit_map``; a Dask LocalCluster against the local run."""

import hashlib
import json
import os
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from torsionfit._errors import InputError
from torsionfit.bench import load_bench, simulate
from torsionfit.accept import load_spec
from torsionfit.batch import (BatchOptions, ROW_FILE, UnitTask, executor, fit_map_batch, group_by_shape, packets,
                              posterior_sample, run_batch, shape_key, stored_row, unit_tasks)
from torsionfit.cli import main
from torsionfit.fit import fit_map
from torsionfit.io import write_campaign
from torsionfit.report import FitOptions, prepare_fit

BENCH = Path(__file__).parent / "benches" / "rv_small_base.toml"
DECIMATE = 4
GOOD = ("unit-a", "unit-b")
SPEC = ("[[requirement]]\nmetric = 'stiffness_elastic'\nmin = 80.0\nunit = 'Nm/arcmin'\n"
        "[[requirement]]\nmetric = 'stiffness_elastic'\nmin = 200.0\nunit = 'Nm/arcmin'\n")


@pytest.fixture(scope="module")
def bench():
    return load_bench(BENCH)


@pytest.fixture(scope="module")
def line(tmp_path_factory, bench):
    """A folder of units: two good SYNTHETIC units (seeds 1, 2), one whose run file is missing
    and one with text in a numeric column."""
    root = tmp_path_factory.mktemp("line")
    for seed, name in enumerate(GOOD, start=1):
        write_campaign(simulate(bench, seed=seed).campaign, root / name, label=bench.label)
    shutil.copytree(root / "unit-a", root / "bad-missing")
    next((root / "bad-missing").glob("*.csv*")).unlink()
    shutil.copytree(root / "unit-a", root / "bad-text")
    csv = next((root / "bad-text").glob("hyst*.csv*"))
    lines = csv.read_text().splitlines()
    lines[5] = ",".join(["oops"] * len(lines[5].split(",")))
    csv.write_text("\n".join(lines) + "\n")
    return root


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("spec") / "spec.toml"
    path.write_text(SPEC)
    return path


def _argv(line, out, *extra, workers=1):
    return ["batch", str(line), "-o", str(out), "--decimate", str(DECIMATE), "--workers", str(workers), *extra]


@pytest.fixture(scope="module")
def first_run(line, spec_file, tmp_path_factory):
    """The folder through the command line, with a spec (stiffness ≥ 80 and ≥ 200 N·m/arcmin), in
    two worker processes (two packets of two units)."""
    out = tmp_path_factory.mktemp("out")
    code = main(_argv(line, out, "--spec", str(spec_file), workers=2))
    return out, code, json.loads((out / "batch.json").read_text())["units"]


def test_bad_units_are_rows_and_the_others_are_done(first_run):
    out, code, rows = first_run
    by_unit = {r["unit"]: r for r in rows}
    assert code == 2  # a unit in error
    assert sorted(by_unit) == ["bad-missing", "bad-text", *GOOD]
    assert by_unit["bad-missing"]["status"] == "error" and "run file not found" in by_unit["bad-missing"]["reason"]
    assert by_unit["bad-text"]["status"] == "error" and "oops" in by_unit["bad-text"]["reason"]
    for r in rows:
        assert "\n" not in r.get("reason", "")
    for name in GOOD:
        r = by_unit[name]
        assert r["status"] == "done" and r["sampler"] == "laplace" and r["map_converged"] is True
        doc = json.loads((out / name / "fit.json").read_text())
        assert r["stiffness_elastic [Nm/arcmin]"] == doc["metrics"]["stiffness_elastic"]["mean"]
        # SYNTHETIC truth 108 N·m/arcmin
        assert abs(r["stiffness_elastic [Nm/arcmin]"] - 108.0) < 5 * r["stiffness_elastic sd"] + 1.0
        # loops see every parameter of the reducer: none left at its prior (the column is there, empty)
        assert r["prior_dominated"] == "" and "prior_dominated_note" not in doc["diagnostics"]
    assert by_unit["unit-a"]["shape"] == by_unit["unit-b"]["shape"]
    for name in GOOD:  # the SYNTHETIC units are far above 80 and far below 200 N·m/arcmin
        r = by_unit[name]
        assert r["decision"] == "reject" and r["p_conform"] == 0.0
        assert r["p_conform[stiffness_elastic >= 80 Nm/arcmin]"] == 1.0
        assert json.loads((out / name / "accept.json").read_text())["decision"] == "reject"
    assert by_unit["bad-text"]["decision"] == "error"
    header = (out / "batch.csv").read_text().splitlines()[0].split(",")
    assert header[:2] == ["unit", "status"] and len((out / "batch.csv").read_text().splitlines()) == 5


def test_rerun_skips_done_units_and_force_redoes_them(first_run, line, spec_file, capsys):
    out, _, rows = first_run
    stamp = {n: (out / n / "fit.json").stat().st_mtime_ns for n in GOOD}
    capsys.readouterr()
    assert main(_argv(line, out, "--spec", str(spec_file))) == 2
    assert "2 already done, 2 to do" in capsys.readouterr().err  # the bad units are tried again
    assert {n: (out / n / "fit.json").stat().st_mtime_ns for n in GOOD} == stamp
    assert json.loads((out / "batch.json").read_text())["units"] == rows
    # a changed setting (the seed) is not "done"
    row = json.loads((out / "unit-a" / ROW_FILE).read_text())
    assert row["settings"]["seed"] == 0
    assert main(_argv(line, out, "--spec", str(spec_file), "--force")) == 2
    assert "0 already done, 4 to do" in capsys.readouterr().err
    assert all((out / n / "fit.json").stat().st_mtime_ns > stamp[n] for n in GOOD)
    # same seed, same numbers: this run in this process, the first in two worker processes
    assert json.loads((out / "batch.json").read_text())["units"] == rows


def test_incomplete_or_changed_units_are_not_done(first_run, line, spec_file, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(first_run[0], out)
    options = BatchOptions(fit=FitOptions(sampler="laplace", progress=False, decimate=DECIMATE),
                           spec=load_spec(spec_file), spec_digest=hashlib.sha256(spec_file.read_bytes()).hexdigest())
    tasks = {t.unit: t for t in unit_tasks(line, out)}
    assert stored_row(tasks["unit-a"], options) == {r["unit"]: r for r in first_run[2]}["unit-a"]
    assert stored_row(tasks["bad-text"], options) is None  # errors are tried again
    assert stored_row(tasks["unit-a"], replace(options, seed=1)) is None
    assert stored_row(tasks["unit-a"], replace(options, spec_digest="another spec")) is None
    assert stored_row(tasks["unit-a"], replace(options, posterior_units=frozenset({"unit-a"}))) is None
    (out / "unit-a" / "accept.json").unlink()
    assert stored_row(tasks["unit-a"], options) is None


def test_vmapped_map_equals_fit_map_per_unit(bench):
    problems = [prepare_fit(simulate(bench, seed=s).campaign, FitOptions(decimate=DECIMATE))[2] for s in (1, 2)]
    assert shape_key(problems[0]) == shape_key(problems[1])
    seeds = [0, 7]  # each unit its own seed: its own starts
    together = fit_map_batch(problems, [("h", "t")] * 2, seeds, lanes="vmap")
    for problem, seed, b in zip(problems, seeds, together):
        a = fit_map(problem, ("h", "t"), seed=seed)
        scale = np.maximum(np.abs(a.u), 1.0)
        assert np.max(np.abs(a.u - b.u) / scale) < 1e-6
        assert np.allclose(a.cov, b.cov, rtol=1e-5, atol=1e-9 * np.max(np.abs(a.cov)))
        assert abs(a.log_density - b.log_density) < 1e-6 * abs(a.log_density)
        assert np.allclose([ld for ld, _ in a.starts], [ld for ld, _ in b.starts], rtol=1e-9)
        assert (a.converged, a.message) == (b.converged, b.message)
        for k in a.values:
            assert np.allclose(a.values[k], b.values[k], rtol=1e-6, atol=1e-12), k


def test_dask_local_cluster_equals_local_run(first_run, line, spec_file, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        options = BatchOptions(fit=FitOptions(sampler="laplace", progress=False, decimate=DECIMATE),
                               spec=load_spec(spec_file), spec_digest="x")
        rows = run_batch(line, tmp_path / "dask", options, scheduler=cluster.scheduler_address)
    local = first_run[2]
    assert [r["unit"] for r in rows] == [r["unit"] for r in local]
    for a, b in zip(rows, local):
        assert a.keys() == b.keys()
        for k in a:
            if k != "campaign":
                assert a[k] == pytest.approx(b[k], rel=1e-9) if isinstance(a[k], float) else a[k] == b[k], (a["unit"], k)


def crash_on_unit_named_crash(packet, options):
    """``fit_group``, but the worker process dies (as on a segfault or the OOM killer: no
    exception) on a unit named "a-crash". Module level: the worker processes import it."""
    from torsionfit.batch import fit_group

    if any(t.unit == "a-crash" for t in packet):
        os._exit(3)
    return fit_group(packet, options)


@pytest.mark.extended
def test_a_worker_process_that_dies_costs_only_its_unit(line, tmp_path, monkeypatch):
    """The pool breaks; the units it may have been fitting are redone one at a time in a process
    of their own, the one that kills it again gets an error row, the others are done."""
    from torsionfit.batch import _batch, run_batch

    root = tmp_path / "in"
    for name in ("a-crash", "unit-a"):
        shutil.copytree(line / "unit-a", root / name)
    monkeypatch.setattr(_batch, "fit_group", crash_on_unit_named_crash)
    said = []
    options = BatchOptions(fit=FitOptions(sampler="laplace", progress=False, decimate=DECIMATE), group_size=2)
    rows = run_batch(root, tmp_path / "out", options, workers=2, progress=said.append)
    status = {r["unit"]: (r["status"], r["reason"]) for r in rows}
    assert status["a-crash"][0] == "error" and "worker process fitting this unit died" in status["a-crash"][1]
    assert status["unit-a"][0] == "done"
    assert any("a worker process died" in text for text in said)
    table = json.loads((tmp_path / "out" / "batch.json").read_text())["units"]
    assert [r["unit"] for r in table] == ["a-crash", "unit-a"]


def crash_on_every_unit(packet, options):
    """``fit_group`` of a worker process that cannot work: it dies on every unit."""
    os._exit(3)


@pytest.mark.extended
def test_worker_processes_that_never_work_end_the_batch_with_one_line(line, tmp_path, monkeypatch):
    """Every unit kills its process (as when a worker cannot start): after STARTUP_DEATHS units
    alone, with no unit ever back, the batch stops with one line instead of trying every unit."""
    from torsionfit.batch import WorkerProcessError, _batch, run_batch

    root = tmp_path / "in"
    for name in ("u1", "u2", "u3", "u4"):
        shutil.copytree(line / "unit-a", root / name)
    monkeypatch.setattr(_batch, "fit_group", crash_on_every_unit)
    options = BatchOptions(fit=FitOptions(sampler="laplace", progress=False, decimate=DECIMATE), group_size=1)
    with pytest.raises(WorkerProcessError, match="3 units in a row each killed a worker process") as err:
        run_batch(root, tmp_path / "out", options, workers=2)
    assert "\n" not in str(err.value) and "--workers 1" in str(err.value)
    dead = [u for u in ("u1", "u2", "u3", "u4") if (tmp_path / "out" / u / ROW_FILE).exists()]
    assert len(dead) == _batch.STARTUP_DEATHS  # the culprits' error rows are written


def test_batch_command_prints_the_worker_process_error_in_one_line(line, tmp_path, monkeypatch, capsys):
    import torsionfit.batch as batch

    def never_works(*args, **kwargs):
        raise batch.WorkerProcessError("3 units in a row each killed a worker process of their own")

    monkeypatch.setattr(batch, "run_batch", never_works)
    assert main(_argv(line, tmp_path / "out", workers=2)) == 2
    err = capsys.readouterr().err.strip()
    assert err == "torsionfit batch: error: 3 units in a row each killed a worker process of their own"


def test_unreachable_scheduler_is_one_line_input_error():
    with pytest.raises(InputError, match="cannot reach a Dask scheduler"):
        with executor("tcp://127.0.0.1:9", timeout_s=2):
            pass


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="CPU affinity is Linux-only")
@pytest.mark.extended
def test_worker_processes_are_pinned_one_cpu_each():
    """JAX sizes its thread pool by the CPUs a process may use: each worker gets one, round robin."""
    from torsionfit.batch._executor import worker_cpus

    usable = sorted(os.sched_getaffinity(0))
    assert worker_cpus(2 * len(usable) + 1) == usable * 2 + usable[:1]
    with executor(workers=2) as run:
        seen = list(run(os.sched_getaffinity, [0] * 8))
    assert all(len(cpus) == 1 and cpus <= set(usable) for cpus in seen)


@pytest.mark.parametrize("backend, expected", [("cpu", None), ("gpu", 1), ("tpu", 1)])
def test_default_workers_one_per_cpu_or_one_per_accelerator(monkeypatch, backend, expected):
    import jax

    from torsionfit.batch import default_workers, usable_cpus

    monkeypatch.setattr(jax, "default_backend", lambda: backend)
    assert default_workers() == (expected or usable_cpus())


def test_packets_keep_emcee_units_apart_and_give_every_worker_work(tmp_path):
    tasks = [UnitTask(f"u{i}", tmp_path / f"u{i}.toml", tmp_path / f"o{i}") for i in range(7)]
    options = BatchOptions(posterior_units=frozenset({"u1", "u4"}), group_size=2)
    sizes = lambda work: [[t.unit for t in p] for p in work]  # noqa: E731
    assert sizes(packets(tasks, options)) == [["u1", "u4"], ["u0", "u2"], ["u3", "u5"], ["u6"]]
    assert sizes(packets(tasks, replace(options, group_size=16), workers=2)) == [["u1"], ["u4"], ["u0", "u2", "u3"],
                                                                               ["u5", "u6"]]
    assert packets([], options, workers=2) == []
    many = [UnitTask(f"u{i:02d}", tmp_path / "m.toml", tmp_path / "o") for i in range(48)]
    assert [len(p) for p in packets(many, BatchOptions(group_size=16), workers=2)] == [12] * 4  # not 16, 16, 16


@pytest.mark.parametrize("extra, message", [(("--workers", "0"), "--workers ≥ 1"),
                                            (("--workers", "2", "--scheduler", "tcp://127.0.0.1:9"),
                                             "--workers is for this machine")])
def test_bad_workers_option_is_one_line_input_error(line, tmp_path, capsys, extra, message):
    argv = ["batch", str(line), "-o", str(tmp_path / "out"), *extra]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_group_by_shape_and_posterior_sample():
    assert group_by_shape(["a", "b", None, "a", "a"], 2) == [[0, 3], [4], [1]]
    with pytest.raises(ValueError):
        group_by_shape(["a"], 0)
    units = [f"u{i}" for i in range(20)]
    chosen = posterior_sample(units, 3, seed=1)
    assert len(chosen) == 3 and chosen == posterior_sample(units[::-1], 3, seed=1)
    assert chosen != posterior_sample(units, 3, seed=2)
    options = BatchOptions(posterior_units=chosen)
    assert {u for u in units if options.sampler_of(u) == "emcee"} == chosen
    assert options.settings_of("u0") != replace(options, seed=5).settings_of("u0")


@pytest.fixture(scope="module")
def good(line, tmp_path_factory):
    folder = tmp_path_factory.mktemp("good")
    for name in GOOD:
        shutil.copytree(line / name, folder / name)
    return folder


@pytest.fixture(scope="module")
def posterior_sample_run(good, tmp_path_factory):
    out = tmp_path_factory.mktemp("sample1")
    code = main(_argv(good, out, "--posterior-sample", "1", "--max-steps", "300"))
    return out, code, json.loads((out / "batch.json").read_text())["units"]


@pytest.mark.slow
def test_posterior_sample_gets_emcee_and_non_convergence_is_in_its_row(posterior_sample_run):
    out, code, rows = posterior_sample_run
    emcee = [r for r in rows if r["sampler"] == "emcee"]
    assert len(emcee) == 1 and code == 4
    assert emcee[0]["converged"] is False and "not converged" in emcee[0]["reason"]
    assert (out / emcee[0]["unit"] / "posterior.nc").is_file()


@pytest.mark.slow
def test_emcee_units_sampled_together_equal_a_unit_sampled_alone(posterior_sample_run, good, tmp_path):
    """--sampler emcee: both units' ensembles advance together (one log-density call for
    both); the unit of the posterior sample, sampled there alone, has the same fit.json."""
    out, _, rows = posterior_sample_run
    alone = next(r["unit"] for r in rows if r["sampler"] == "emcee")
    assert main(_argv(good, tmp_path / "all", "--sampler", "emcee", "--max-steps", "300")) == 4
    both = json.loads((tmp_path / "all" / "batch.json").read_text())["units"]
    assert all(r["sampler"] == "emcee" and r["converged"] is False and "not converged" in r["reason"] for r in both)
    a = json.loads((out / alone / "fit.json").read_text())
    b = json.loads((tmp_path / "all" / alone / "fit.json").read_text())
    for key, value in a["diagnostics"].items():
        assert b["diagnostics"][key] == (pytest.approx(value, rel=1e-9) if isinstance(value, float) else value), key
    for name, m in a["metrics"].items():
        for key in ("mean", "sd"):
            assert b["metrics"][name][key] == pytest.approx(m[key], rel=1e-9), (name, key)
