"""An absolute encoder's wrap in a hysteresis angle is unwrapped on reading, with a note the
metrics table, its JSON and fit.json show. SYNTHETIC paper-large from data/; REAL measured
loop from ../shared/data (skipped when absent)."""

import gzip
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from torsionfit.cli import main
from torsionfit.io import load_campaign
from torsionfit.io._wrap import unwrap_full_turns
from torsionfit.metrics import campaign_metrics
from torsionfit.report._pipeline import _runs_json

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"
EXAMPLES = ROOT / "examples" / "cycloidal-jv"
SHARED = ROOT.parent / "shared" / "data" / "cycloidal-jv"
TURN_ARCMIN = 360 * 60


def test_steps_of_a_full_turn_are_taken_out_and_no_others():
    twist = 0.02 * np.sin(np.linspace(0.0, 6 * math.pi, 600))  # rad, crossing zero five times inside
    wrapped = np.mod(twist, 2 * math.pi)  # an encoder reading 0 to 2π
    unwrapped, count = unwrap_full_turns(wrapped)
    assert count == 5  # the zero crossings at π, 2π, … 5π
    np.testing.assert_allclose(unwrapped - unwrapped[0], twist - twist[0], atol=1e-12)
    signed = np.mod(twist, 2 * math.pi) - math.pi  # an encoder reading -π to π, the twist at its ends
    unwrapped, count = unwrap_full_turns(signed)
    assert count == 5
    np.testing.assert_allclose(unwrapped - unwrapped[0], twist - twist[0], atol=1e-12)
    jumpy = twist.copy()
    jumpy[300:] += 0.5 * 2 * math.pi  # half a turn: not an encoder's wrap, left as it is
    np.testing.assert_array_equal(unwrap_full_turns(jumpy)[0], jumpy)
    assert unwrap_full_turns(twist)[1] == 0


def _wrapped_paper_large(tmp_path: Path) -> Path:
    folder = tmp_path / "wrapped"
    shutil.copytree(DATA / "paper-large", folder)
    for path in folder.glob("hysteresis*.csv"):
        lines = path.read_text().splitlines()
        head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
        k = lines[head].split(",").index("angle_arcmin")
        rows = [line.split(",") for line in lines[head + 1:]]
        for row in rows:
            row[k] = repr(float(row[k]) % TURN_ARCMIN)  # 0 to 21600 arcmin, wrapping at each zero
        path.write_text("\n".join(lines[:head + 1] + [",".join(r) for r in rows]) + "\n")
    return folder / "campaign.toml"


def test_a_wrapped_angle_reads_as_the_original_and_says_so(tmp_path, capsys):
    path = _wrapped_paper_large(tmp_path)
    wrapped, original = load_campaign(path), load_campaign(DATA / "paper-large" / "campaign.toml")
    for a, b in zip(wrapped.hysteresis_runs, original.hysteresis_runs):
        offset = a.angle_rad - b.angle_rad  # the first sample's turn, kept
        np.testing.assert_allclose(offset, offset[0], atol=1e-9)
        assert [n for n in a.notes if "wraps at a full turn" in n]
    m_wrapped = campaign_metrics(wrapped)["runs"][0]
    m_original = campaign_metrics(original)["runs"][0]
    for name in ("stiffness_elastic", "lost_motion", "play"):
        assert m_wrapped["metrics"][name]["value"] == pytest.approx(m_original["metrics"][name]["value"], rel=1e-6)
    assert any("angle_arcmin" in n and "unwrapped on reading" in n for n in m_wrapped["reading"])
    assert m_original["reading"] == []
    assert main(["metrics", str(path)]) == 0
    assert "  read: column 'angle_arcmin' wraps at a full turn" in capsys.readouterr().out
    assert main(["metrics", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["runs"][0]["reading"] == m_wrapped["reading"]
    runs = _runs_json(wrapped, temperature_term=False)["runs"]  # fit.json's runs
    assert runs["hysteresis-1Nm_per_s"]["reading"] == list(wrapped.runs[0].notes)


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
def test_a_measured_loop_read_by_a_wrapping_encoder_gives_the_original_play(tmp_path):
    """REAL split initial-pos1, POSITION (rev) moved to cross a full turn and read modulo one:
    read as it is it stopped on the angle's sign; unwrapped, its play is the original's."""
    lines = gzip.open(SHARED / "split-pccf" / "initial-pos1.csv.gz", "rt").read().splitlines()
    k = lines[0].split(",").index("POSITION")
    rows = [line.split(",") for line in lines[1:]]
    values = np.array([float(r[k]) for r in rows])
    centre = 0.5 * (values.min() + values.max())
    for row, v in zip(rows, values):
        row[k] = repr(float((v - centre) % 1.0))
    (tmp_path / "wrap.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    text = (EXAMPLES / "split-pccf-initial-pos1.toml").read_text()
    (tmp_path / "wrap.toml").write_text(
        text.replace("../../../shared/data/cycloidal-jv/split-pccf/initial-pos1.csv.gz", "wrap.csv"))
    run = campaign_metrics(load_campaign(tmp_path / "wrap.toml"))["runs"][0]
    original = campaign_metrics(load_campaign(EXAMPLES / "split-pccf-initial-pos1.toml"))["runs"][0]
    assert run["metrics"]["play"]["value"] == pytest.approx(original["metrics"]["play"]["value"], rel=1e-9)
    assert any("'POSITION' wraps at a full turn" in n for n in run["reading"])
