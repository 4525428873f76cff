"""Execute the research notebooks (notebooks/*.ipynb, stored without outputs) and write the
executed copies, with their outputs, to docs/notebooks/ for the documentation site.

    .venv/bin/python scripts/render_notebooks.py [--small] [NAME ...]

Full settings by default (each notebook says what they are; the measured-data notebook reads
../shared/data — REAL data, CC BY-SA 4.0 — and is skipped with a message when it is absent);
``--small``: the test suite's small settings. The stored notebooks are never changed.
"""

import argparse
import os
import sys
import time
from pathlib import Path

import nbformat
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "notebooks"
TARGET = ROOT / "docs" / "notebooks"
SHARED_DATA = ROOT.parent / "shared" / "data"
SMALL_SETTINGS = {"TORSIONFIT_NOTEBOOK_SMALL": "1", "TORSIONFIT_NOTEBOOK_DECIMATE": "64"}


def render(path: Path, small: bool, timeout_s: int) -> str:
    nb = nbformat.read(path, as_version=4)
    if nb.metadata.get("torsionfit", {}).get("needs_shared_data") and not SHARED_DATA.is_dir():
        return f"{path.name}: skipped, it reads measured data from {SHARED_DATA}, which is absent"
    # no MPLBACKEND: the kernel's inline backend puts the figures into the outputs
    env = {k: v for k, v in dict(os.environ, **(SMALL_SETTINGS if small else {})).items() if k != "MPLBACKEND"}
    old = os.environ.copy()
    os.environ.clear()
    os.environ.update(env)  # the kernel inherits this process's environment
    try:
        t0 = time.perf_counter()
        NotebookClient(nb, timeout=timeout_s, kernel_name="python3",
                       resources={"metadata": {"path": str(SOURCE)}}).execute()
    finally:
        os.environ.clear()
        os.environ.update(old)
    nb.metadata.setdefault("torsionfit", {})["rendered_with"] = "small settings" if small else "full settings"
    out = TARGET / path.name
    if out.is_symlink() or out.exists():
        out.unlink()
    nbformat.write(nb, out)
    return f"{path.name}: executed in {time.perf_counter() - t0:.0f} s → {out.relative_to(ROOT)}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="notebook names (default: all)")
    parser.add_argument("--small", action="store_true", help="the test suite's small settings")
    parser.add_argument("--timeout", type=int, default=3600, help="per cell, seconds")
    args = parser.parse_args(argv)
    TARGET.mkdir(parents=True, exist_ok=True)
    paths = sorted(SOURCE.glob("*.ipynb"))
    if args.names:
        paths = [p for p in paths if p.stem in args.names or p.name in args.names]
    for path in paths:
        print(render(path, args.small, args.timeout), file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
