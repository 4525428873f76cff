"""The CLI's persistent compilation cache (torsionfit/_cache.py)."""

import subprocess
import sys

import pytest

from torsionfit._cache import default_cache_dir, enable_compilation_cache


@pytest.mark.parametrize("value", ["off", "OFF", "", "0", "none"])
def test_the_environment_switches_the_cache_off(monkeypatch, value):
    monkeypatch.setenv("TORSIONFIT_CACHE_DIR", value)
    assert default_cache_dir() is None
    assert enable_compilation_cache() is None


def test_default_folder_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.delenv("TORSIONFIT_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / "torsionfit" / "jax"


def test_an_unwritable_folder_only_costs_compile_time(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert enable_compilation_cache(blocker / "jax") is None


def test_a_second_process_reads_what_the_first_compiled(tmp_path):
    """Compile in one process, then check that a fresh process finds the program on disk
    (JAX counts persistent-cache hits in ``jax.monitoring``)."""
    script = f"""
import jax, jax.numpy as jnp, jax.monitoring
hits = []
jax.monitoring.register_event_listener(lambda event, **kw: hits.append(event) if 'cache_hits' in event else None)
from torsionfit._cache import enable_compilation_cache
enable_compilation_cache({str(tmp_path / 'cache')!r})
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)  # this tiny program compiles fast
f = jax.jit(lambda x: jnp.cumsum(jnp.sin(x) ** 2) @ jnp.cos(x))
f(jnp.linspace(0, 1, 4096)).block_until_ready()
print(len(hits))
"""
    env_cmd = [sys.executable, "-c", script]
    first = subprocess.run(env_cmd, capture_output=True, text=True, check=True)
    assert any((tmp_path / "cache").iterdir()), first.stderr
    second = subprocess.run(env_cmd, capture_output=True, text=True, check=True)
    assert int(second.stdout.split()[-1]) >= 1, second.stderr
