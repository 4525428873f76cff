"""Tempered SMC's checkpoint (sample/_smc_checkpoint.py): a run stopped after a stage resumes from
its file and ends draw for draw where the run without the stop ends; a checkpoint of other
settings or of another posterior stops with one line naming the file."""

import numpy as np
import pytest

from torsionfit.sample import tempered_smc

from test_sample_smc import _narrow_start, _target, _target_and_grad

DIM = 4
MEAN = np.array([1.0, -0.5, 0.3, 0.8])
COV = np.diag([1.0, 2.0, 0.5, 1.5])


class _Stop(Exception):
    """Stands for the process ending (a restart, a time limit) after a stage."""


def _stop_after(stage):
    def progress(line):
        if line.startswith(f"[smc] stage {stage}:"):
            raise _Stop(line)
    return progress


def _run(kind, checkpoint=None, seed=3, progress=None, resume=True, **kw):
    target = ({"log_p_and_grad": _target_and_grad(MEAN, COV)} if kind == "hmc" else {})
    return tempered_smc(_target(MEAN, COV), _narrow_start(DIM), np.random.default_rng(seed), kw.pop("n", 300),
                        checkpoint=checkpoint, resume=resume, progress=progress, names=[f"p{i}" for i in range(DIM)],
                        **target, **kw)


@pytest.mark.parametrize("kind", ["hmc", "random walk"])
def test_a_run_stopped_after_a_stage_resumes_and_ends_where_the_unstopped_run_ends(tmp_path, kind):
    whole = _run(kind)
    assert len(whole.betas) >= 3  # stops after stage 2 leave stages to go
    path = tmp_path / "smc.npz"
    with pytest.raises(_Stop):
        _run(kind, checkpoint=path, progress=_stop_after(2), resume=False)
    assert path.is_file() and not list(tmp_path.glob("*.tmp"))  # written whole, no leftovers
    lines = []
    # another generator: the checkpoint's state replaces it
    resumed = _run(kind, checkpoint=path, seed=99, progress=lines.append)
    assert lines[0].startswith(f"[smc] resumed from {path} after stage 2")
    np.testing.assert_array_equal(resumed.chain, whole.chain)
    np.testing.assert_array_equal(resumed.log_prob, whole.log_prob)
    assert resumed.betas == whole.betas and resumed.stage_moves == whole.stage_moves
    assert resumed.stage_correlation == whole.stage_correlation and resumed.converged == whole.converged
    assert resumed.approximation_pareto_k == whole.approximation_pareto_k
    assert resumed.stage_leapfrog_steps == whole.stage_leapfrog_steps
    # the finished run's checkpoint gives its result again without moving a particle
    again = _run(kind, checkpoint=path, seed=7)
    np.testing.assert_array_equal(again.chain, whole.chain)
    assert again.betas == whole.betas


def test_a_checkpoint_of_other_settings_stops_with_one_line(tmp_path):
    path = tmp_path / "smc.npz"
    with pytest.raises(_Stop):
        _run("hmc", checkpoint=path, progress=_stop_after(1))
    with pytest.raises(ValueError, match=r"smc\.npz: an SMC checkpoint made with particles = 300, this run asks 400"):
        _run("hmc", checkpoint=path, n=400)
    with pytest.raises(ValueError, match="made with kernel = 'hmc', this run asks 'random walk'"):
        _run("random walk", checkpoint=path)


def test_a_checkpoint_of_another_posterior_stops_with_one_line(tmp_path):
    path = tmp_path / "smc.npz"
    with pytest.raises(_Stop):
        _run("hmc", checkpoint=path, progress=_stop_after(1))
    other = MEAN + 0.1  # other data: the same settings, another posterior
    with pytest.raises(ValueError, match=r"smc\.npz: the posterior's log density at the checkpoint's particles is not "
                                         r"the one it was saved with"):
        tempered_smc(_target(other, COV), _narrow_start(DIM), np.random.default_rng(3), 300, checkpoint=path,
                     log_p_and_grad=_target_and_grad(other, COV), resume=True, names=[f"p{i}" for i in range(DIM)])


def test_a_file_that_is_no_checkpoint_stops_with_one_line(tmp_path):
    path = tmp_path / "smc.npz"
    path.write_text("not a checkpoint")
    with pytest.raises(ValueError, match=r"smc\.npz: not an SMC checkpoint"):
        _run("hmc", checkpoint=path)


def test_without_resume_a_checkpoint_is_started_afresh_and_overwritten(tmp_path):
    path = tmp_path / "smc.npz"
    with pytest.raises(_Stop):
        _run("hmc", checkpoint=path, progress=_stop_after(1), seed=5)
    fresh = _run("hmc", checkpoint=path, resume=False)
    np.testing.assert_array_equal(fresh.chain, _run("hmc").chain)  # seed 3's run, not seed 5's
    # the file is now the finished seed-3 run's
    np.testing.assert_array_equal(_run("hmc", checkpoint=path, seed=11).chain, fresh.chain)
