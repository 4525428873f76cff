"""Time stamps against the rates the manifest declares: a time column in ms read as s (or in
min) stops with one line naming the column and the key; the bundled, bench-written and measured
campaigns never do. SYNTHETIC campaigns from data/; REAL measured loops from ../shared/data."""

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from torsionfit import InputError
from torsionfit.io import load_campaign
from torsionfit.io._time_scale import RATE_RATIO_LIMIT, check_loading_rate, excursion_rate_Nm_per_s, turning_points

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"
EXAMPLES = ROOT / "examples" / "cycloidal-jv"
SHARED = ROOT.parent / "shared" / "data" / "cycloidal-jv"


def _scaled_copy(tmp_path: Path, pattern: str = "", column: str = "", factor: float = 1.0) -> Path:
    """paper-large copied with ``column`` of the files matching ``pattern`` multiplied by ``factor``."""
    folder = tmp_path / "paper-large"
    shutil.copytree(DATA / "paper-large", folder)
    for path in folder.glob(pattern) if pattern else ():
        lines = path.read_text().splitlines()
        head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
        k = lines[head].split(",").index(column)
        rows = [line.split(",") for line in lines[head + 1:]]
        for row in rows:
            row[k] = repr(float(row[k]) * factor)
        path.write_text("\n".join(lines[:head + 1] + [",".join(r) for r in rows]) + "\n")
    return folder / "campaign.toml"


def test_turning_points_keep_reversals_beyond_the_threshold_only():
    x = np.array([0, 1, 2, 3, 2, 2.5, 1, 0, -1, -2, -1, 0, 1, 2, 1.0])
    # the 0.5 dip at index 4 and the last 1.0 fall are not reversals
    assert turning_points(x, 1.5) == [0, 3, 9, 14]
    assert turning_points(x, 0.9) == [0, 3, 9, 13, 14]


def test_the_excursion_rate_reads_ramps_through_noise_spikes_holds_and_play_cycles():
    """A triangle of ±40 N·m at 8 N·m/s with 3 s holds at the peaks, ±4 N·m play cycles at
    another rate, noise and spikes (a motor-current torque): the median excursion rate is the
    ramps' rate; a sine's is its mean rate over 10–90 % of a half-cycle."""
    rng = np.random.default_rng(1)
    dt = 0.01
    ramp = np.linspace(-40.0, 40.0, int(10.0 / dt))
    hold_hi, hold_lo = np.full(300, 40.0), np.full(300, -40.0)
    play = np.concatenate([np.linspace(0, 4, 200), np.linspace(4, -4, 400), np.linspace(-4, 0, 200)] * 3)
    torque = np.concatenate([play, np.linspace(0, -40, 500), hold_lo]
                            + [ramp, hold_hi, ramp[::-1], hold_lo] * 3)
    torque = torque + rng.normal(0.0, 0.5, torque.size)
    torque[rng.choice(torque.size, 40, replace=False)] += 15.0
    t = np.arange(torque.size) * dt
    rate, count = excursion_rate_Nm_per_s(t, torque)
    assert rate == pytest.approx(8.0, rel=0.05) and count >= 6
    sine_t = np.linspace(0.0, 60.0, 6001)
    rate, _ = excursion_rate_Nm_per_s(sine_t, 40.0 * np.sin(2 * np.pi * sine_t / 20.0))
    # between 10 % and 90 % of a half-cycle: 32 N·m over (asin(0.8) + asin(0.8))·20/2π s
    assert rate == pytest.approx(64.0 / (2 * np.arcsin(0.8) * 20.0 / (2 * np.pi)), rel=0.02)
    check_loading_rate(sine_t, 40.0 * np.sin(2 * np.pi * sine_t / 20.0), 4 * np.pi, "f.csv", "t", "s", "T", "Nm")


def test_the_bundled_campaigns_ramp_at_their_declared_rates():
    for name in ("paper-large", "paper-small"):
        for run in load_campaign(DATA / name / "campaign.toml").hysteresis_runs:
            rate, _ = excursion_rate_Nm_per_s(run.time_s, run.torque_Nm)
            assert rate == pytest.approx(run.loading_rate_Nm_per_s, rel=0.02), (name, run.name)


@pytest.mark.parametrize("factor, how", [(1000.0, "slower"), (1 / 60.0, "faster")])
def test_a_time_column_in_another_unit_stops_on_the_loading_rate(tmp_path, factor, how):
    path = _scaled_copy(tmp_path, "hysteresis*.csv", "time_s", factor)
    with pytest.raises(InputError) as err:
        load_campaign(path)
    message = str(err.value)
    assert "\n" not in message and "hysteresis-1Nm_per_s.csv" in message
    assert "column 'time_s'" in message and "loading_rate_Nm_per_s = 1" in message
    assert '[runs.units] time = "ms"' in message
    times = float(re.search(rf"([0-9.]+)× {how} than the declared", message).group(1))
    assert times == pytest.approx(max(factor, 1 / factor), rel=0.02)


def test_a_loading_rate_within_the_limit_reads_and_beyond_it_stops(tmp_path):
    path = _scaled_copy(tmp_path)
    text = path.read_text()
    assert "loading_rate_Nm_per_s = 1.0" in text
    path.write_text(text.replace("loading_rate_Nm_per_s = 1.0", "loading_rate_Nm_per_s = 2.0"))
    load_campaign(path)  # a nominal rate 2× off: the ramps' own rate is still plausible
    path.write_text(text.replace("loading_rate_Nm_per_s = 1.0", f"loading_rate_Nm_per_s = {RATE_RATIO_LIMIT * 1.1}"))
    with pytest.raises(InputError, match=r"ramps at 0\.99\d* N·m/s .*loading_rate_Nm_per_s = 4\.4"):
        load_campaign(path)


def _without_time(tmp_path: Path, rate_Hz: float | None) -> Path:
    """paper-large with the hysteresis files' time column removed and ``sample_rate_Hz`` set
    (None: removed)."""
    path = _scaled_copy(tmp_path)
    for csv in path.parent.glob("hysteresis*.csv"):
        lines = csv.read_text().splitlines()
        head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
        k = lines[head].split(",").index("time_s")
        csv.write_text("\n".join(lines[:head] + [",".join(c for j, c in enumerate(line.split(",")) if j != k)
                                                 for line in lines[head:]]) + "\n")
    text = path.read_text().replace("sample_rate_Hz = 10.0\n", "" if rate_Hz is None else f"sample_rate_Hz = {rate_Hz}\n")
    path.write_text(text)
    return path


def test_a_hysteresis_run_without_a_time_column_is_timed_by_the_sample_rate(tmp_path):
    """A bench that logs torque and angle at a fixed rate, without time stamps: with [instrument]
    sample_rate_Hz the run is timed by it (noted), reads as with its time column and gives the same
    metrics; at a rate 10× off the loading rate stops it with one line; without a rate, the
    missing column's line names the key."""
    from torsionfit.metrics import campaign_metrics

    original = load_campaign(DATA / "paper-large" / "campaign.toml")
    timed = load_campaign(_without_time(tmp_path / "a", 10.0))
    for a, b in zip(original.hysteresis_runs, timed.hysteresis_runs):
        np.testing.assert_allclose(b.time_s, a.time_s - a.time_s[0], atol=1e-9)
        assert "time from [instrument] sample_rate_Hz = 10 (no time column)" in b.notes
    assert campaign_metrics(timed)["runs"][0]["metrics"] == campaign_metrics(original)["runs"][0]["metrics"]
    with pytest.raises(InputError, match=r"hysteresis-1Nm_per_s\.csv: column 'torque_Nm' ramps at 9\.9\d* N·m/s sampled at "
                                         r"\[instrument\] sample_rate_Hz = 100 .*loading_rate_Nm_per_s = 1;"):
        load_campaign(_without_time(tmp_path / "b", 100.0))
    with pytest.raises(InputError, match=r"no time column: .* \(or declare \[instrument\] sample_rate_Hz for a run"):
        load_campaign(_without_time(tmp_path / "c", None))


def test_a_te_time_column_in_ms_stops_on_the_speed(tmp_path):
    path = _scaled_copy(tmp_path, "te-*.csv", "time_s", 1000.0)
    with pytest.raises(InputError) as err:
        load_campaign(path)
    message = str(err.value)
    assert "\n" not in message and "te-" in message and "column 'time_s'" in message
    assert "(speed_rpm)" in message and "slower than the declared output speed" in message


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
def test_the_measured_loops_ramp_at_8_Nm_per_s():
    """REAL: the 21 measured files' large ramps run at 8 N·m/s (±40 N·m in 10 s) by their TIME
    column; declared so, every file reads; declared in ms, every one stops."""
    manifests = sorted(EXAMPLES.glob("*.toml"))
    assert len(manifests) == 21
    for manifest in manifests:
        run = load_campaign(manifest).hysteresis_runs[0]
        rate, count = excursion_rate_Nm_per_s(run.time_s, run.torque_Nm)
        assert rate == pytest.approx(8.0, rel=0.03) and count >= 6, manifest.name
        check_loading_rate(run.time_s, run.torque_Nm, 8.0, manifest.name, "TIME", "s", "TORQUE", "Nm")
        with pytest.raises(InputError, match=manifest.name):
            check_loading_rate(run.time_s * 1000.0, run.torque_Nm, 8.0, manifest.name, "TIME", "ms", "TORQUE", "Nm")
