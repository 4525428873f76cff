"""The NumPy reference used by benchmarks/bench_hysteresis_scan.py equals the JAX model.

Not a timing test: it keeps the benchmark honest (the NumPy loop computes the same thing).
"""

import importlib.util
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import torsionfit.model as m

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "_numpy_model.py"
_spec = importlib.util.spec_from_file_location("_bench_numpy_model", _PATH)
ref = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ref)


def five_step(rated_Nm=100.0, rate_Nm_per_s=10.0, samples_per_step=60):
    step = rated_Nm / rate_Nm_per_s
    t = np.linspace(0, 5 * step, 5 * samples_per_step + 1)
    return t, np.interp(t, step * np.arange(6), rated_Nm * np.array([0, 1, 0, -1, 0, 1.0]))


PARAMS = dict(
    stiffness=2.0e5, friction_torque=3.0, dahl_torque=1.5, gap=2e-4, gap_torque=2.0,
    creep_stiffness=1.0e6, creep_time=5.0, angle_offset=jnp.array([1e-4]),
)


def walker_params(n_walkers, seed=0):
    rng = np.random.default_rng(seed)
    out = {}
    for k, v in PARAMS.items():
        v = np.asarray(v, float)
        out[k] = jnp.asarray(v * (1 + 0.2 * rng.uniform(-1, 1, (n_walkers,) + v.shape)))
    return out


@pytest.mark.parametrize("scan", ["associative", "serial"])
def test_numpy_reference_equals_jax_model(scan):
    model = m.CampaignModel(run_kinds=("hysteresis",), creep=m.Creep(), scan=scan)
    t, tau = five_step()
    inp = m.hysteresis_input(t, tau)
    want = jax.jit(lambda p, x: model.components(p, [x])[0])(PARAMS, inp)
    got = ref.components(PARAMS, t, tau)
    for name in (*ref.COMPONENTS, "total", "mesh_torque", "friction_state"):
        np.testing.assert_allclose(got[name], want[name], rtol=0, atol=1e-10, err_msg=name)
    # the loop has hysteresis and creep in it: a zero model would pass nothing
    assert np.ptp(got["friction_state"]) > 1.5 and np.ptp(got["creep"]) > 1e-5


@pytest.mark.parametrize("scan", ["associative", "serial"])
def test_numpy_walkers_equal_vmapped_jax_model(scan):
    model = m.CampaignModel(run_kinds=("hysteresis",), creep=m.Creep(), scan=scan)
    t, tau = five_step(samples_per_step=40)
    inp = m.hysteresis_input(t, tau)
    batch = walker_params(5)
    want = jax.jit(jax.vmap(lambda p, x: model.predict(p, [x])[0], in_axes=(0, None)))(batch, inp)
    got = ref.predict(batch, t, tau)
    assert got.shape == (5, len(t))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10)
    # each walker is the single-parameter-set reference with that walker's values
    one = {k: v[3] for k, v in batch.items()}
    np.testing.assert_allclose(got[3], ref.predict(one, t, tau), rtol=0, atol=1e-15)
