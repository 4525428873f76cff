"""What a benchmark ran on: CPU, versions, JAX backend and the settings that change timings."""

import datetime as dt
import os
import platform

import jax
import numpy as np


def machine(**versions: str) -> dict:
    """A description of this machine and process; ``versions`` adds ``name=version`` pairs
    (e.g. scipy's) to the versions line."""
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        cpu = platform.processor() or platform.machine()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    import jaxlib

    extra = "".join(f", {name} {version}" for name, version in versions.items())
    cache = jax.config.jax_compilation_cache_dir
    return {
        "date": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu": f"{cpu}, {os.cpu_count()} logical CPUs ({usable} usable by this process)",
        "python": platform.python_version(),
        "versions": f"jax {jax.__version__} (jaxlib {jaxlib.__version__}), numpy {np.__version__}{extra}",
        "backend": f"{jax.default_backend()} ({', '.join(str(d) for d in jax.devices())}), "
                   f"float64 {'on' if jax.config.jax_enable_x64 else 'off'}",
        "threads": f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}, "
                   f"XLA_FLAGS={os.environ.get('XLA_FLAGS', '(unset)')}, persistent JAX compilation cache "
                   f"{'on: ' + str(cache) if cache else 'off'}",
    }


def write_report(path, lines: list[str]) -> None:
    """Write a benchmark's Markdown lines to ``path`` (folders made) and print them."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
