"""``torsionfit paper``: every figure, ``tables.json`` and the comparison page into one folder;
and the entry point of the one-figure scripts under ``paper_figures/``."""

import argparse
import json
import sys
import time
from pathlib import Path

from .._x64 import in_float64
from .._errors import InputError
from .._provenance import provenance
from ._document import paper_document
from ._page import comparison_page
from ._reproduction import Reproduction
from ._settings import PaperSettings, paper_settings
from .figures import FIGURES


def _one_line(func) -> str:
    return " ".join((func.__doc__ or "").strip().split("\n\n")[0].split())


@in_float64
def make_figures(repro: Reproduction, out_dir, keys=None) -> list[Path]:
    """The figures ``keys`` (default all, :data:`FIGURES`) as PNG and PDF in ``out_dir``."""
    keys = list(FIGURES) if keys is None else list(keys)
    unknown = [k for k in keys if k not in FIGURES]
    if unknown:
        raise InputError(f"unknown figure {unknown[0]!r}; expected one of {', '.join(FIGURES)}")
    paths = []
    for key in keys:
        repro.progress(f"figure {key}")
        t0 = time.perf_counter()
        paths += FIGURES[key](repro, out_dir)
        repro.timings[f"figure {key}"] = time.perf_counter() - t0
    return paths


@in_float64
def run_paper(out_dir, settings: PaperSettings, data_dir=None, progress=None, command: str = "torsionfit paper") -> dict:
    """Write ``out_dir/figures/*.png|pdf``, ``out_dir/tables.json`` and ``out_dir/README.md``
    (the comparison page); returns the ``tables.json`` document."""
    t0 = time.perf_counter()
    out = Path(out_dir)
    repro = Reproduction(settings, data_dir, progress)
    doc = paper_document(repro)
    paths = make_figures(repro, out / "figures")
    doc["figures"] = [str(p.relative_to(out)) for p in paths]
    doc["runtime_s"] = {"total": time.perf_counter() - t0, **repro.timings}
    doc["provenance"] = provenance(settings.seed, command)
    out.mkdir(parents=True, exist_ok=True)
    (out / "tables.json").write_text(json.dumps(doc, indent=2, ensure_ascii=False))
    write_page(out, command)
    return doc


def write_page(out_dir, command: str = "torsionfit paper") -> Path:
    """``out_dir/README.md``, the comparison page, from ``out_dir/tables.json`` alone."""
    out = Path(out_dir)
    source = out / "tables.json"
    if not source.is_file():
        raise InputError(f"{source}: not found; run torsionfit paper -o {out} first")
    doc = json.loads(source.read_text())
    lines = [(f.__name__, _one_line(f)) for f in FIGURES.values()]
    (out / "README.md").write_text(comparison_page(doc, lines, command))
    return out / "README.md"


@in_float64
def figure_script(key: str, argv=None) -> int:
    """``python paper_figures/<figure>.py -o DIR [--quick] [--seed N] [--data DIR]``: one figure."""
    parser = argparse.ArgumentParser(description=_one_line(FIGURES[key]))
    parser.add_argument("-o", "--output", type=Path, default=Path("paper-figures"), help="output folder")
    parser.add_argument("--quick", action="store_true", help="quick settings (Laplace approximation, slowest loop only, decimated)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--data", type=Path, default=None, help="folder holding paper-small/ and paper-large/")
    args = parser.parse_args(argv)
    say = lambda text: print(f"[paper] {text}", file=sys.stderr, flush=True)  # noqa: E731
    try:
        paths = make_figures(Reproduction(paper_settings(args.quick, args.seed), args.data, say), args.output, [key])
    except InputError as err:
        print(f"{key}: error: {err}", file=sys.stderr)
        return 2
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0
