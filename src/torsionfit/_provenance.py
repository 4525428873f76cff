"""What made a JSON output: torsionfit's version, the seed and the command line, recorded in
every document the commands write (``"provenance"``)."""

import shlex


def command_line(argv) -> str:
    """``torsionfit ARG ...`` as a shell would take it back (arguments quoted where needed)."""
    return shlex.join(["torsionfit", *map(str, argv)])


def provenance(seed: int | None, command: str | None = None) -> dict:
    """``{"torsionfit_version", "seed", "command"}``; ``seed`` None for deterministic outputs,
    ``command`` None when written by a Python call rather than the command line."""
    from . import __version__

    return {"torsionfit_version": __version__, "seed": seed, "command": command}
