"""Command line: --help, simulate, metrics, and one-line errors with a non-zero exit."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from torsionfit.cli import EXIT_INPUT_ERROR, main

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "tests" / "benches" / "rv_small_base.toml"


def test_help_lists_the_commands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for command in ("simulate", "metrics"):
        assert command in out


def test_entry_point_runs():
    proc = subprocess.run([sys.executable, "-m", "torsionfit.cli", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "simulate" in proc.stdout


def test_simulate_then_metrics_json(tmp_path, capsys):
    assert main(["simulate", str(BENCH), "-o", str(tmp_path / "c"), "--seed", "3"]) == 0
    capsys.readouterr()
    assert main(["metrics", str(tmp_path / "c" / "campaign.toml"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    kinds = {r["name"]: r["kind"] for r in result["runs"]}
    assert kinds == {"hyst-5": "hysteresis", "te-5rpm-fw": "transmission_error"}
    hyst = next(r for r in result["runs"] if r["kind"] == "hysteresis")["metrics"]
    for name in ("stiffness_rated", "lost_motion", "backlash", "dissipated_energy"):
        assert set(hyst[name]) >= {"value", "unit"}
    te = next(r for r in result["runs"] if r["kind"] == "transmission_error")["metrics"]
    assert te["kd"]["unit"] == "Nm/arcmin" and "kt" in te


def test_metrics_table_mentions_synthetic(tmp_path, capsys):
    main(["simulate", str(BENCH), "-o", str(tmp_path / "c")])
    capsys.readouterr()
    assert main(["metrics", str(tmp_path / "c")]) == 0
    out = capsys.readouterr().out
    assert "SYNTHETIC" in out and "stiffness_rated" in out


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["metrics", "no/such/campaign.toml"], "campaign manifest not found"),
        (["simulate", "no/such/bench.toml", "-o", "x"], "bench file not found"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, fragment, capsys):
    assert main(argv) == EXIT_INPUT_ERROR
    err = capsys.readouterr().err
    assert fragment in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_bad_manifest_through_the_real_entry_point(tmp_path):
    manifest = tmp_path / "campaign.toml"
    manifest.write_text('[reducer]\nname = "x"\nrated_torqe_Nm = 5\n')
    proc = subprocess.run([sys.executable, "-m", "torsionfit.cli", "metrics", str(manifest)],
                          capture_output=True, text=True)
    assert proc.returncode == EXIT_INPUT_ERROR
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1
    assert "rated_torqe_Nm" in proc.stderr
