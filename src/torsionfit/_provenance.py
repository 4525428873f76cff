"""What made a JSON output: torsionfit's version, the seed, the command line and the numerical
environment, recorded in every document the commands write (``"provenance"``)."""

import platform
import shlex
from importlib import metadata

#: the packages whose versions move a fit's last digits (compiled programs, linear algebra)
NUMERICAL_PACKAGES = ("jax", "jaxlib", "numpy", "scipy", "equinox", "optimistix", "lineax")


def command_line(argv) -> str:
    """``torsionfit ARG ...`` as a shell would take it back (arguments quoted where needed)."""
    return shlex.join(["torsionfit", *map(str, argv)])


#: the vector instruction sets XLA's CPU code generation chooses between
VECTOR_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512_bf16", "avx512_fp16", "amx_tile")


def _cpu() -> str:
    """The processor's model name and vector instruction sets (``/proc/cpuinfo`` where there is
    one): XLA compiles for the host's instruction set, so the same program may round differently
    on another processor."""
    model, flags = platform.processor() or platform.machine(), []
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                key, _, value = line.partition(":")
                if key.strip().lower() == "model name":
                    model = value.strip()
                elif key.strip().lower() == "flags":
                    present = set(value.split())
                    flags = [f for f in VECTOR_FLAGS if f in present]
                    break
    except OSError:
        pass
    return f"{model} ({' '.join(flags)})" if flags else model


def environment() -> dict:
    """``{"python", "cpu", <package>: version, ...}``: what a re-run must match to give a fit to
    the last digit (a fit is deterministic on one environment; another one's rounding moves a
    MAP within the solver's tolerance)."""
    versions = {}
    for name in NUMERICAL_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return {"python": platform.python_version(), "cpu": _cpu(), **versions}


def provenance(seed: int | None, command: str | None = None) -> dict:
    """``{"torsionfit_version", "seed", "command", "environment"}``; ``seed`` None for
    deterministic outputs, ``command`` None when written by a Python call rather than the
    command line."""
    from . import __version__

    return {"torsionfit_version": __version__, "seed": seed, "command": command, "environment": environment()}
