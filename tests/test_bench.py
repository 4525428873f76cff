"""Virtual bench: bench files, protocol, sensors, seeds (SYNTHETIC data throughout)."""

from pathlib import Path

import numpy as np
import pytest

from torsionfit import InputError
from torsionfit.bench import five_step_protocol, load_bench, simulate
from torsionfit.units import ANGLE_UNITS

BENCHES = Path(__file__).parent / "benches"
BASE = BENCHES / "rv_small_base.toml"


def test_five_step_protocol_shape():
    t, tau = five_step_protocol(10.0, 2.0, 10.0)
    assert t[-1] == pytest.approx(25.0)  # five steps of 10 N·m at 2 N·m/s
    n = len(t) - 1
    assert tau[n // 5] == pytest.approx(10.0) and tau[2 * n // 5] == pytest.approx(0.0)
    assert tau[3 * n // 5] == pytest.approx(-10.0) and tau[-1] == pytest.approx(10.0)
    t2, tau2 = five_step_protocol(10.0, 2.0, 10.0, cycles=2, dwell_s=3.0)
    assert t2[-1] == pytest.approx(45.0 + 5 * 3.0)  # 9 ramps, 5 dwells at the peaks


def test_simulation_is_seeded_and_labelled_synthetic():
    bench = load_bench(BASE)
    a, b, c = simulate(bench), simulate(bench), simulate(bench, seed=99)
    np.testing.assert_array_equal(a.campaign.runs[0].angle_rad, b.campaign.runs[0].angle_rad)
    assert not np.array_equal(a.campaign.runs[0].torque_Nm, c.campaign.runs[0].torque_Nm)
    assert "synthetic" in a.campaign.notes.lower()


def test_sensor_models():
    bench = load_bench(BASE)
    sim = simulate(bench)
    hyst, te = sim.campaign.runs
    res = ANGLE_UNITS["arcsec"]
    # encoder quantisation: readings (at the 180° position) are whole encoder steps
    steps = (hyst.angle_rad + np.pi) / res
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    # torque noise: accuracy 0.1 % of 1500 N·m full scale, as one standard deviation
    noise = hyst.torque_Nm - sim.measured_torque_true[0]
    assert np.std(noise) == pytest.approx(1.5, rel=0.1)
    # TE run: one revolution at 720 samples, the twist of 380 N·m ≈ 380/108 arcmin + half the gap
    assert np.ptp(te.output_angle_rad) == pytest.approx(2 * np.pi, abs=2 * np.pi / 720)  # jittered clocked samples
    te_arcmin = np.mean(te.te_rad) / ANGLE_UNITS["arcmin"]
    assert te_arcmin == pytest.approx(386 / 108 + 0.5, rel=0.02)


def test_effects_stay_out_of_the_manifest(tmp_path):
    text = BASE.read_text().replace("[truth]", "[effects]\nrate_dependence = true\n[truth]\ncreep_stiffness_Nm_per_arcmin = 900\ncreep_time_s = 30")
    bench_file = tmp_path / "bench.toml"
    bench_file.write_text(text)
    from torsionfit.cli import main

    assert main(["simulate", str(bench_file), "-o", str(tmp_path / "out")]) == 0
    manifest = (tmp_path / "out" / "campaign.toml").read_text()
    assert "creep" not in manifest and "effects" not in manifest and "truth" not in manifest
    assert "SYNTHETIC" in manifest
    for csv in (tmp_path / "out").glob("*.csv*"):
        assert "SYNTHETIC" in csv.read_text().splitlines()[0]


def test_rate_dependence_effect_changes_the_data():
    bench = load_bench(BASE)
    plain = simulate(bench).components[0]["total"]
    crept = simulate(
        load_bench_with(BASE, "[effects]\nrate_dependence = true\n", "creep_stiffness_Nm_per_arcmin = 900\ncreep_time_s = 30\n")
    ).components[0]["total"]
    assert np.max(np.abs(np.asarray(plain) - np.asarray(crept))) > 1e-5


def test_gap_steps_effect_moves_the_gap_crossing():
    """A gap taken up in steps (``gap_steps``) simulates: with most of the gap at the last step
    the loading branch crosses it later than with the smooth gap; without its shares in
    [truth] the bench stops with one line."""
    bench = load_bench(BASE)
    plain = simulate(bench).components[0]["geometric"]
    stepped = simulate(load_bench_with(BASE, "[effects]\ngap_steps = {steps = 3, span_Nm = 60.0}\n",
                                       "gap_step_logits = [-4.0, 4.0]\n")).components[0]["geometric"]
    plain, stepped = np.asarray(plain), np.asarray(stepped)
    assert np.ptp(stepped) == pytest.approx(np.ptp(plain), rel=1e-3)  # the same gap β
    assert np.max(np.abs(stepped - plain)) > 0.3 * np.ptp(plain)  # crossed elsewhere
    with pytest.raises(InputError, match="gap_step_logits"):
        simulate(load_bench_with(BASE, "[effects]\ngap_steps = {steps = 3, span_Nm = 60.0}\n", ""))


def load_bench_with(path, effects, truth_extra, tmp=[]):
    import tempfile

    text = path.read_text().replace("[truth]", effects + "[truth]\n" + truth_extra)
    d = Path(tempfile.mkdtemp())
    f = d / "bench.toml"
    f.write_text(text)
    return load_bench(f)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda s: s.replace("[truth]", "[truth]\nstifness_Nm_per_arcmin = 3"), "unknown truth parameter"),
        (lambda s: s.replace("gap_arcmin", "gap_furlong"), "unit 'furlong' not accepted"),
        (lambda s: s.replace("dahl_torque_Nm = 4.0", ""), "missing parameter 'dahl_torque'"),
        (lambda s: s.replace('direction = "forward"', 'direction = "sideways"'), "direction"),
        (lambda s: s.replace("seed = 1", "seed = 1\ncolour = 3"), "unknown key 'colour'"),
        (lambda s: s.replace('kind = "hysteresis"', 'kind = "torque_ramp"'), "kind"),
        (lambda s: s.replace("rated_torque_Nm = 380.0", "rated_torque_Nm = -1"), "positive"),
        (lambda s: s.replace("sample_rate_Hz = 5.0", ""), "sample_rate_Hz"),
        (lambda s: s.replace("[truth]", "[effects]\nkinematic_error = [1.5]\n[truth]"), "kinematic_error"),
        (lambda s: s.replace("[truth]", "[effects]\nwarp_drive = true\n[truth]"), "unknown key 'warp_drive'"),
        (lambda s: s + "\n[[", "TOML syntax error"),
        (lambda s: s.replace("[truth]", "[noise]\njump_share = 1.5\njump_arcsec = 10.0\n[truth]"), r"jump_share: expected a share"),
        (lambda s: s.replace("[truth]", "[noise]\njump_share = 0.1\njump_arcsec = -10.0\n[truth]"), r"jump_arcsec: expected a jump size"),
        (lambda s: s.replace("[truth]", "[effects]\ntemperature_dependence = true\n[truth]\ntemperature_compliance_per_K = 0.003\n"
                             "temperature_friction_per_K = -0.02"), "temperature_dependence needs every run's temperature_C"),
    ],
)
def test_bad_bench_files(tmp_path, edit, message):
    f = tmp_path / "bench.toml"
    f.write_text(edit(BASE.read_text()))
    with pytest.raises(InputError, match=message):
        simulate(load_bench(f))


def test_missing_bench_file(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_bench(tmp_path / "nope.toml")


def test_te_runs_have_clock_time_in_both_directions(tmp_path):
    """TE samples are clocked: time rises in backward runs too, and survives a write/read."""
    from torsionfit.io import load_campaign, write_campaign

    text = BASE.read_text().replace('direction = "forward"', 'direction = "backward"')
    f = tmp_path / "bench.toml"
    f.write_text(text)
    sim = simulate(load_bench(f))
    te = sim.campaign.runs[1]
    assert te.direction == -1 and np.all(np.diff(te.time_s) > 0)
    assert np.diff(te.output_angle_rad).mean() < 0
    back = load_campaign(write_campaign(sim.campaign, tmp_path / "out"))
    np.testing.assert_allclose(back.runs[1].time_s, te.time_s)


def test_jumps_move_their_share_of_the_samples_by_their_size():
    """[noise] jump_share / jump_arcsec: that share of the angle samples off the noise-free
    loop by the jump (here ±40″ against 1″ noise)."""
    jumps = load_bench(BENCHES / "stat_rv_jumps.toml")
    sim = simulate(jumps, seed=3)
    run = next(r for r in sim.campaign.runs if r.kind == "hysteresis")
    clean = np.asarray(sim.components[sim.campaign.runs.index(run)]["total"])
    off = np.abs(np.asarray(run.angle_rad) - clean) / ANGLE_UNITS["arcsec"]
    share = np.mean(off > 20.0)
    assert abs(share - jumps.noise.jump_share) < 0.005
    assert np.all(np.abs(off[off > 20.0] - 40.0) < 8.0)
