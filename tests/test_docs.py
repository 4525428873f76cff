"""The documentation: the site builds in strict mode (any warning fails: a broken link, a page
missing from the nav, a docstring the API reference cannot parse), the getting-started manifest
reads the export it describes, and the README stays a newcomer's page."""

import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "docs" / "examples" / "my-bench"


def test_site_builds_strict(tmp_path):
    pytest.importorskip("mkdocs", reason="the docs extra is not installed (pip install -e '.[docs]')")
    # mkdocs' own executable beside this interpreter: the venv's, whatever PATH says
    mkdocs = Path(sys.executable).with_name("mkdocs")
    command = [str(mkdocs) if mkdocs.exists() else "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")]
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # no end-of-life banner in the log
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120, env=env)
    log = done.stdout + done.stderr
    warnings = [line for line in log.splitlines() if line.startswith(("WARNING", "ERROR"))]
    assert done.returncode == 0 and not warnings, "mkdocs build --strict failed:\n" + "\n".join(warnings or log.splitlines()[-30:])
    site = tmp_path / "site"
    # the API reference lists the re-exported names (an empty page would also build cleanly)
    io_page = (site / "reference" / "io" / "index.html").read_text()
    assert 'id="torsionfit.io.load_campaign"' in io_page
    # the notebooks are rendered as pages
    assert (site / "notebooks" / "hysteresis_paper_large" / "index.html").is_file()


def test_getting_started_manifest_reads_its_export(tmp_path):
    """The manifest shown on the getting-started page reads the SYNTHETIC export the page makes,
    and the data-only elastic slope is the bench's true stiffness."""
    sys.path.insert(0, str(EXAMPLE))
    try:
        from make_export import BENCH, write_export
    finally:
        sys.path.remove(str(EXAMPLE))
    from torsionfit.io import load_campaign
    from torsionfit.metrics import campaign_metrics

    write_export(tmp_path)
    shutil.copy(EXAMPLE / "campaign.toml", tmp_path / "campaign.toml")
    campaign = load_campaign(tmp_path)
    (run,) = campaign.runs
    lines = (tmp_path / "loop_export.csv").read_text().splitlines()
    data_rows = sum(1 for line in lines[2:] if line.endswith(";OK"))
    assert len(run) == data_rows  # [runs.select] dropped exactly the SETUP rows
    truth = tomllib.loads(BENCH.read_text())["truth"]["stiffness_Nm_per_arcmin"]
    elastic = campaign_metrics(campaign)["runs"][0]["metrics"]["stiffness_elastic"]
    assert elastic["unit"] == "Nm/arcmin"
    assert elastic["value"] == pytest.approx(truth, rel=0.02)


# user-facing text names no issue numbers, work sessions or commit hashes
_HEX = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")
# (the words alone stay allowed: "issues a warning", "a Python session")
_FORBIDDEN = re.compile(r"\b(issue|session|PR)s?\s*#?\s*\d+|#\d+|\bpull request|\bthe issue's|"
                        r"\b(this|that|an earlier|a previous|the previous|the last|a later) (session|issue)\b",
                        re.IGNORECASE)


def _user_facing() -> list[Path]:
    return [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))


@pytest.mark.parametrize("path", _user_facing(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_issue_numbers_sessions_or_hashes(path):
    text = path.read_text(encoding="utf-8")
    found = [(n, m.group()) for n, line in enumerate(text.splitlines(), 1)
             for m in (*_HEX.finditer(line), *_FORBIDDEN.finditer(line))]
    assert not found, f"{path.relative_to(ROOT)}: {found[:5]}"


def test_readme_manifest_reads_the_simulated_loop(tmp_path):
    """The README's minimal manifest reads the loop file `torsionfit simulate` writes."""
    from torsionfit.bench import load_bench, simulate
    from torsionfit.io import load_campaign, write_campaign

    bench = ROOT / "tests" / "benches" / "rv_small_base.toml"
    write_campaign(simulate(load_bench(bench)).campaign, tmp_path)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    manifest = re.search(r"```toml\n(.*?)```", readme, re.S).group(1)
    (tmp_path / "campaign.toml").write_text(manifest)
    (run,) = load_campaign(tmp_path).runs
    assert run.name == "hyst-5" and run.kind == "hysteresis"
    # the CSV lines the README shows are the file's first lines
    shown = re.search(r"```text\n(.*?)```", readme, re.S).group(1).splitlines()
    assert (tmp_path / "hyst-5.csv").read_text().splitlines()[: len(shown)] == shown


def test_readme_is_a_newcomers_page():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250
    for needed in ("make run", "make test", "<!-- zoo:begin -->", "<!-- zoo:end -->"):
        assert needed in text, f"README.md lacks {needed!r}"
    assert text.index("<!-- zoo:begin -->") < text.index("<!-- zoo:end -->")
