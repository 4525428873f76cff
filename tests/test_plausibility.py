"""Plausibility warnings (a unit slip of 60× or 3600×, a TE run against its declared direction,
a torque far past the rating), the decimal-comma hint, and errors that name their file."""

import math
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from torsionfit import InputError
from torsionfit.cli import main
from torsionfit.io import PlausibilityWarning, load_campaign
from torsionfit.io._plausibility import (
    TWIST_MIN_ARCMIN,
    check_te_direction,
    quantisation_step,
    twist_band_arcmin,
)
from torsionfit.io._read import read_table

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"
EXAMPLES = ROOT / "examples" / "cycloidal-jv"
SHARED = ROOT.parent / "shared" / "data" / "cycloidal-jv"
ARCMIN = math.pi / (180 * 60)


def plausibility_warnings(path) -> list[str]:
    """Messages of the PlausibilityWarnings that loading ``path`` gives (each one line)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_campaign(path)
    out = [str(w.message) for w in caught if issubclass(w.category, PlausibilityWarning)]
    assert all("\n" not in m for m in out)
    return out


def relabelled(tmp_path, name: str, old: str, new: str, values=None) -> Path:
    """The bundled campaign ``name`` copied with column ``old`` renamed to ``new`` in its
    hysteresis files, the values optionally mapped by ``values`` (text → text of a cell)."""
    folder = tmp_path / name
    shutil.copytree(DATA / name, folder)
    for path in folder.glob("hysteresis*.csv"):
        lines = path.read_text().splitlines()
        head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
        columns = lines[head].split(",")
        k = columns.index(old)
        columns[k] = new
        rows = [line.split(",") for line in lines[head + 1:]]
        if values is not None:
            for row in rows:
                row[k] = values(row[k])
        path.write_text("\n".join(lines[:head] + [",".join(columns)] + [",".join(r) for r in rows]) + "\n")
    return folder / "campaign.toml"


# ----------------------------------------------------------------------------- no false alarms


@pytest.mark.parametrize("name", ["paper-large", "paper-small"])
def test_bundled_synthetic_campaigns_raise_no_warning(name):
    assert plausibility_warnings(DATA / name / "campaign.toml") == []


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
@pytest.mark.parametrize("manifest", sorted(p.name for p in EXAMPLES.glob("*.toml")))
def test_measured_cycloidal_loops_raise_no_warning(manifest):
    """REAL measured 3D-printed cycloidal loops (twist ~100–170 arcmin at 20 N·m, play up to
    2.6°): the softest real units the checks must accept."""
    assert plausibility_warnings(EXAMPLES / manifest) == []


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
def test_measured_loop_without_a_rating_raises_no_warning(write_files):
    """Without rated_torque_Nm the twist is judged at the loop's own peak (±40 N·m here)."""
    text = (EXAMPLES / "split-pccf-initial-pos1.toml").read_text()
    text = text.replace("rated_torque_Nm = 20.0", "").replace(
        "../../../shared/data/cycloidal-jv", SHARED.as_posix())
    path = write_files({"campaign.toml": text + "[runs.select]\ntest_nr = [100, 101, 102]\n"})
    assert plausibility_warnings(path) == []


# ----------------------------------------------------------------------------- unit slips


def without_resolution(path: Path) -> Path:
    """``path`` (a campaign.toml) with its [instrument] encoder_resolution_arcsec taken out."""
    text = path.read_text()
    assert "encoder_resolution_arcsec" in text
    path.write_text(re.sub(r"encoder_resolution_arcsec = [0-9.]+\n", "", text))
    return path


def test_arcmin_under_a_deg_header_stops_when_the_encoder_step_agrees(tmp_path):
    """paper-large (380 N·m, ~4.4 arcmin at rated): its arcmin column read as degrees twists
    ~260 arcmin, above the 138 arcmin a 380 N·m reducer can, and moves in steps 60× its declared
    1″ encoder: both readings say arcmin, so the declaration is contradicted — one line, stop."""
    path = relabelled(tmp_path, "paper-large", "angle_arcmin", "angle_deg")
    with pytest.raises(InputError) as err:
        load_campaign(path)
    message = str(err.value)
    assert "\n" not in message and "hysteresis-1Nm_per_s.csv" in message and "column 'angle_deg' read as deg" in message
    assert "60× the [instrument] encoder_resolution_arcsec = 1" in message and "rated torque 380 N·m" in message
    assert "both fit the column holding arcmin (steps of 1 arcsec, a twist of 4.43 arcmin): declare its unit arcmin" in message


def test_arcmin_under_a_deg_header_is_a_warning_on_one_reading_alone(tmp_path):
    """The same slip without a declared resolution: the twist alone says so, a warning (a twist can
    be unusual); with the resolution mistyped, the step alone does not stop either."""
    path = without_resolution(relabelled(tmp_path, "paper-large", "angle_arcmin", "angle_deg"))
    found = plausibility_warnings(path)
    twist = [m for m in found if "twists" in m]
    assert len(twist) == 3 and not [m for m in found if "moves in steps" in m]  # one per hysteresis run
    assert "hysteresis-1Nm_per_s.csv" in twist[0] and "column 'angle_deg'" in twist[0]
    assert "if the column held arcmin" in twist[0] and "rated torque 380 N·m" in twist[0]
    # the resolution 7× off the step: no unit factor, no stop (the step warning is for 20× and more)
    text = path.read_text().replace("[instrument]\n", "[instrument]\nencoder_resolution_arcsec = 7.0\n", 1)
    assert "encoder_resolution_arcsec = 7.0" in text
    path.write_text(text)
    assert len([m for m in plausibility_warnings(path) if "twists" in m]) == 3


def test_deg_under_an_arcmin_header_is_caught_60x(tmp_path):
    """The other way: the angles 60× too small make a twist of ~0.07 arcmin at 380 N·m; with the
    encoder step agreeing (1/60″ against 1″) it stops, on the twist alone it warns."""
    path = relabelled(tmp_path, "paper-large", "angle_arcmin", "angle_arcmin",
                      values=lambda cell: repr(float(cell) / 60.0))
    with pytest.raises(InputError, match="both fit the column holding deg"):
        load_campaign(path)
    twist = [m for m in plausibility_warnings(without_resolution(path)) if "twists" in m]
    assert len(twist) == 3
    assert f"{TWIST_MIN_ARCMIN:g}–138 arcmin" in twist[0]


def test_arcsec_under_a_deg_header_is_caught_3600x(tmp_path):
    """paper-small (1 N·m, a soft ~125 arcmin at rated) values ×60 under angle_deg: 3600×."""
    path = relabelled(tmp_path, "paper-small", "angle_arcmin", "angle_deg",
                      values=lambda cell: repr(float(cell) * 60.0))  # the arcsec number
    twist = [m for m in plausibility_warnings(without_resolution(path)) if "twists" in m]
    assert len(twist) == 3 and "if the column held arcsec" in twist[0]


@pytest.mark.parametrize("rated", [0.5, 1.0, 20.0, 100.0, 380.0, 3000.0])
def test_a_3600x_slip_of_any_plausible_twist_leaves_the_band(rated):
    """The band spans less than 3600×, so no plausible twist stays plausible after a 3600× slip."""
    low, high = twist_band_arcmin(rated)
    assert high / low < 3600
    for twist in np.geomspace(low, high, 50):
        assert not low <= 3600 * twist <= high and not low <= twist / 3600 <= high


def test_catalog_reducers_are_inside_the_band():
    """Catalog twists at rated torque (secant, half the lost motion included): RV-20E
    167 N·m / 49 N·m/arcmin + 0.5′, CSF-25 harmonic ~7′ at 67 N·m, a precision planetary
    ~10′ at 100 N·m, a budget planetary ~40′ at 380 N·m, a hobby planetary ~60′ at 3 N·m."""
    for rated, twist in ((167, 167 / 49 + 0.5), (67, 7.0), (100, 10.0), (380, 40.0), (3, 60.0)):
        low, high = twist_band_arcmin(rated)
        assert low <= twist <= high, (rated, twist)


def test_a_resolution_declared_coarser_than_the_steps_is_caught(tmp_path):
    """paper-large moves in steps of its declared 1″; declared as 3″ (as a datasheet's "repeatable
    to three counts" might be read), the steps are finer than the resolution claims and the fit's
    noise floor would be 3× the data's: one warning per hysteresis run. A step coarser than the
    resolution (several counts at once) is not warned about below 20×."""
    folder = tmp_path / "c"
    shutil.copytree(DATA / "paper-large", folder)
    path = folder / "campaign.toml"
    text = path.read_text()
    assert "encoder_resolution_arcsec = 1.0" in text
    path.write_text(text.replace("encoder_resolution_arcsec = 1.0", "encoder_resolution_arcsec = 3.0"))
    found = [m for m in plausibility_warnings(path) if "finer than" in m]
    assert len(found) == 3 and "steps of 1 arcsec" in found[0] and "3×" in found[0], found
    path.write_text(text.replace("encoder_resolution_arcsec = 1.0", "encoder_resolution_arcsec = 0.25"))
    assert plausibility_warnings(path) == []


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
def test_the_readmes_rounded_resolution_on_a_measured_loop_is_caught(write_files):
    """REAL measured loop: the data README's "about 0.016°" (57.6″) is three of the 19.78″
    steps POSITION moves in."""
    text = (EXAMPLES / "split-pccf-initial-pos1.toml").read_text().replace(
        "../../../shared/data/cycloidal-jv", SHARED.as_posix())
    text = re.sub(r"encoder_resolution_arcsec = [0-9.]+", "encoder_resolution_arcsec = 57.6", text)
    found = plausibility_warnings(write_files({"campaign.toml": text}))
    assert len(found) == 1 and "steps of 19.78 arcsec, finer than" in found[0], found


def rewritten_measured_loop(tmp_path, write_files, column: str, factor: float) -> Path:
    """The manifest of REAL measured loop split preload3-pos5 reading a copy of its file in
    ``tmp_path`` (never in the repository) with ``column`` multiplied by ``factor``."""
    import gzip

    lines = gzip.open(SHARED / "split-pccf" / "preload3-pos5.csv.gz", "rt").read().splitlines()
    k = lines[0].split(",").index(column)
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[k] = repr(float(row[k]) * factor)
    (tmp_path / "loop.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    text = (EXAMPLES / "split-pccf-preload3-pos5.toml").read_text()
    text = re.sub(r'file = ".*"', f'file = "{(tmp_path / "loop.csv").as_posix()}"', text)
    return write_files({"campaign.toml": text})


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
def test_a_measured_loop_in_degrees_declared_in_revolutions_stops(tmp_path, write_files):
    """REAL measured loop whose POSITION (output revolutions) is written in degrees, as another
    bench's export might: its 19.78″ encoder steps become 360× the declared resolution and its
    twist 360× a printed reducer's; the reader stops naming the column and the unit both fit."""
    with pytest.raises(InputError) as err:
        load_campaign(rewritten_measured_loop(tmp_path, write_files, "POSITION", 360.0))
    message = str(err.value)
    assert "column 'POSITION' read as rev" in message and "360× the [instrument] encoder_resolution_arcsec" in message
    assert "declare its unit deg" in message


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
def test_a_measured_loop_in_newton_millimetres_declared_in_newton_metres_stops(tmp_path, write_files):
    """REAL measured loop whose TORQUE is written in N·mm: a peak of 40 000 N·m against the
    assumed 20 N·m rating and a twist of 0.1 arcmin at it agree on N·mm."""
    with pytest.raises(InputError) as err:
        load_campaign(rewritten_measured_loop(tmp_path, write_files, "TORQUE", 1000.0))
    message = str(err.value)
    assert "column 'TORQUE' read as Nm reaches" in message and "declare its unit Nmm" in message


def test_an_input_angle_not_divided_by_the_ratio_is_named(tmp_path):
    """paper-large (ratio 121, ~4.4 arcmin at rated) with its angle column written at the motor,
    121× the output's: the twist warning names the input angle and the ratio as a reading that
    fits (beside the units that would)."""
    path = relabelled(tmp_path, "paper-large", "angle_arcmin", "angle_arcmin", lambda v: repr(121.0 * float(v)))
    twist = [m for m in plausibility_warnings(path) if "twists" in m]
    assert len(twist) == 3
    assert "if the column held the input angle, to be divided by [reducer] ratio = 121" in twist[0], twist[0]


def test_torque_in_Nmm_under_a_Nm_header_is_caught(tmp_path):
    """With a loading rate declared, the ramps' rate contradicts it and the run stops, naming the
    torque column with the time column; without, the peak load (2000× the rating) and the twist
    (0.004 arcmin at it) agree on N·mm and it stops naming the unit both fit; with a rating that
    makes the twist plausible as read, the peak alone is a warning."""
    path = relabelled(tmp_path, "paper-large", "torque_Nm", "torque_Nm",
                      values=lambda cell: repr(float(cell) * 1000.0))
    with pytest.raises(InputError, match=r"column 'torque_Nm' ramps at .* 99\d\.\d× faster than the declared "
                                         r"loading_rate_Nm_per_s .*column 'torque_Nm' \(read in Nm\)"):
        load_campaign(path)
    text = re.sub(r"loading_rate_Nm_per_s = [0-9.]+\n", "", path.read_text())
    path.write_text(text)
    with pytest.raises(InputError) as err:
        load_campaign(path)
    message = str(err.value)
    assert "column 'torque_Nm' read as Nm reaches" in message and "rated torque 380 N·m" in message
    assert "both fit the column holding Nmm" in message and "declare its unit Nmm" in message
    assert "or, if the column is right, [reducer] rated_torque_Nm is 1000× too small" in message
    # rated at 1 N·m, the twist as read (about 0.01 arcmin) is still implausible but no smaller
    # unit brings the peak (about 380 000 N·m read) within 10× the rating: warnings only
    path.write_text(re.sub(r"rated_torque_Nm = [0-9.]+", "rated_torque_Nm = 1.0", text))
    found = plausibility_warnings(path)
    peak = [m for m in found if "reaches |torque|" in m]
    assert len(peak) == 3 and "column 'torque_Nm'" in peak[0] and "N·mm" in peak[0]


def test_quantisation_step_is_found_only_on_quantised_data():
    rng = np.random.default_rng(0)
    smooth = np.cumsum(rng.normal(0.0, 1.0, 2000))
    assert quantisation_step(smooth) is None  # unquantised
    q = 2.5e-5
    assert quantisation_step(np.round(smooth / 7.0) * q) == pytest.approx(q)
    assert quantisation_step(np.round(smooth / 7.0) * q + rng.normal(0, q / 10, 2000)) is None


# ----------------------------------------------------------------------------- angle sign


def _negate(cell: str) -> str:
    return repr(-float(cell))


def test_a_reversed_angle_stops_with_one_line_naming_the_column(tmp_path):
    """A bench that counts the angle the other way reads cleanly and gives a loop run the wrong
    way round (the measured play read −66.6 arcmin): the run stops, naming the file, the columns
    and the key that declares it."""
    path = relabelled(tmp_path, "paper-large", "angle_arcmin", "angle_arcmin", _negate)
    with pytest.raises(InputError) as err:
        load_campaign(path)
    message = str(err.value)
    assert "\n" not in message and "hysteresis-1Nm_per_s.csv" in message
    assert "column 'angle_arcmin' falls as column 'torque_Nm' rises" in message
    assert "declare angle_sign = -1 for this run" in message


def test_angle_sign_declares_a_reversed_angle_and_contradicting_it_stops(tmp_path):
    """``angle_sign = -1`` negates the column on reading: the metrics are the original's. The
    same key on a file whose angle grows with torque stops, saying to drop it."""
    from torsionfit.metrics import campaign_metrics

    path = relabelled(tmp_path, "paper-large", "angle_arcmin", "angle_arcmin", _negate)
    text = path.read_text()
    path.write_text(text.replace('kind = "hysteresis"', 'kind = "hysteresis"\nangle_sign = -1'))
    assert text.count('kind = "hysteresis"') == 3
    flipped = load_campaign(path)
    original = load_campaign(DATA / "paper-large" / "campaign.toml")
    for a, b in zip(flipped.runs, original.runs):
        if a.kind == "hysteresis":
            np.testing.assert_allclose(a.angle_rad, b.angle_rad, atol=1e-12)
            assert any("angle_sign = -1" in note for note in a.notes)
    m_flipped, m_original = campaign_metrics(flipped)["runs"][0], campaign_metrics(original)["runs"][0]
    assert m_flipped["metrics"]["stiffness_elastic"]["value"] == pytest.approx(
        m_original["metrics"]["stiffness_elastic"]["value"], rel=1e-9)
    wrong = tmp_path / "wrong" / "campaign.toml"
    shutil.copytree(DATA / "paper-large", wrong.parent)
    wrong.write_text(wrong.read_text().replace('kind = "hysteresis"', 'kind = "hysteresis"\nangle_sign = -1'))
    with pytest.raises(InputError, match=r"falls as column 'torque_Nm' rises .*drop angle_sign = -1"):
        load_campaign(wrong)


@pytest.mark.parametrize("key", ["angle_sign", "torque_sign"])
@pytest.mark.parametrize("value", ["2", "true", '"-1"', "0"])
def test_a_sign_other_than_plus_or_minus_one_is_one_line(tmp_path, key, value):
    folder = tmp_path / "c"
    shutil.copytree(DATA / "paper-large", folder)
    path = folder / "campaign.toml"
    path.write_text(path.read_text().replace('kind = "hysteresis"', f'kind = "hysteresis"\n{key} = {value}', 1))
    with pytest.raises(InputError, match=rf"runs\[0\].*{key} must be 1 .* or -1"):
        load_campaign(path)


def _declared(path: Path, *keys: str) -> Path:
    text = path.read_text()
    assert text.count('kind = "hysteresis"') == 3
    declared = "".join(f"\n{key} = -1" for key in keys)
    path.write_text(text.replace('kind = "hysteresis"', 'kind = "hysteresis"' + declared))
    return path


def test_a_reversed_torque_stops_and_reads_with_torque_sign(tmp_path):
    """A torque sensor counted the other way contradicts like a reversed angle; the message names
    both keys, since only the bench's conventions tell which. ``torque_sign = -1`` gives the
    original's torque; declaring both signs, or the sign on a file that needs none, stops."""
    path = relabelled(tmp_path, "paper-large", "torque_Nm", "torque_Nm", _negate)
    with pytest.raises(InputError) as err:
        load_campaign(path)
    message = str(err.value)
    assert "\n" not in message and "column 'angle_arcmin' falls as column 'torque_Nm' rises" in message
    assert "angle_sign = -1" in message and "torque_sign = -1" in message
    flipped = load_campaign(_declared(path, "torque_sign"))
    original = load_campaign(DATA / "paper-large" / "campaign.toml")
    for a, b in zip(flipped.runs, original.runs):
        if a.kind == "hysteresis":
            np.testing.assert_allclose(a.torque_Nm, b.torque_Nm, atol=1e-12)
            np.testing.assert_allclose(a.angle_rad, b.angle_rad, atol=1e-12)
            assert any("torque_sign = -1" in note for note in a.notes)
    both = relabelled(tmp_path / "both", "paper-large", "torque_Nm", "torque_Nm", _negate)
    with pytest.raises(InputError, match=r"angle_sign = -1 and torque_sign = -1 cancel"):
        load_campaign(_declared(both, "angle_sign", "torque_sign"))
    wrong = tmp_path / "wrong" / "campaign.toml"
    shutil.copytree(DATA / "paper-large", wrong.parent)
    with pytest.raises(InputError, match=r"drop torque_sign = -1"):
        load_campaign(_declared(wrong, "torque_sign"))


def test_a_rigid_units_noise_never_reads_as_a_reversed_angle():
    """Twist below the angle noise (a slope of either sign inside the scatter) and a drift in time
    never stop a run; a reversed angle does, loaded both ways or one way only."""
    from torsionfit.io._convention import check_twist_sign

    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 40.0, 4000)
    torque = 100.0 * np.sin(2 * np.pi * t / 10.0)
    noise = 2.0 * ARCMIN * rng.standard_normal(t.size)
    for slope in (-1e-3 * ARCMIN, 0.0, 1e-3 * ARCMIN):  # ±0.1 arcmin at the ends, noise 2 arcmin
        check_twist_sign(t, torque, slope * torque + noise, "f.csv", "angle", "torque")
    # a drift in time across less than a cycle (the ends visited once each) is not the load's
    check_twist_sign(t[:1000], torque[:1000], 0.1 * t[:1000], "f.csv", "angle", "torque")
    with pytest.raises(InputError, match="f.csv: column 'angle' falls"):
        check_twist_sign(t, torque, -0.1 * ARCMIN * torque + noise, "f.csv", "angle", "torque")
    with pytest.raises(InputError, match="falls"):  # untimed: the drift in samples
        check_twist_sign(None, torque, -0.1 * ARCMIN * torque + noise, "f.csv", "angle", "torque")
    with pytest.raises(InputError, match="falls"):  # loaded one way only
        check_twist_sign(t, np.abs(torque), -0.1 * ARCMIN * np.abs(torque) + noise, "f.csv", "angle", "torque")


def _measured_copy_negated(tmp_path, column: str) -> str:
    """The REAL split initial-pos1 file copied to tmp_path/flip.csv with ``column`` negated, and its
    example manifest pointed at it (written to flip.toml; its text returned)."""
    import gzip

    lines = gzip.open(SHARED / "split-pccf" / "initial-pos1.csv.gz", "rt").read().splitlines()
    k = lines[0].split(",").index(column)
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[k] = _negate(row[k])
    (tmp_path / "flip.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    text = (EXAMPLES / "split-pccf-initial-pos1.toml").read_text()
    text = text.replace("../../../shared/data/cycloidal-jv/split-pccf/initial-pos1.csv.gz", "flip.csv")
    (tmp_path / "flip.toml").write_text(text)
    return text


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
def test_a_measured_loop_with_its_angle_reversed_stops_and_reads_with_angle_sign(tmp_path):
    """REAL measured loop (split initial-pos1), its POSITION negated in a temporary copy: it
    stops; declared with angle_sign = -1 its play reads as the original file's."""
    from torsionfit.metrics import campaign_metrics

    text = _measured_copy_negated(tmp_path, "POSITION")
    with pytest.raises(InputError, match=r"flip.csv: column 'POSITION' falls as column 'TORQUE' rises"):
        load_campaign(tmp_path / "flip.toml")
    (tmp_path / "flip.toml").write_text(text.replace('kind = "hysteresis"', 'kind = "hysteresis"\nangle_sign = -1'))
    play = campaign_metrics(load_campaign(tmp_path / "flip.toml"))["runs"][0]["metrics"]["play"]["value"]
    original = campaign_metrics(load_campaign(EXAMPLES / "split-pccf-initial-pos1.toml"))["runs"][0]["metrics"]["play"]
    assert play == pytest.approx(original["value"], rel=1e-9) and play > 0


@pytest.mark.skipif(not SHARED.is_dir(), reason="measured data ../shared/data/cycloidal-jv is absent")
def test_a_measured_loop_with_its_torque_reversed_needs_torque_sign_not_angle_sign(tmp_path):
    """REAL measured loop (split initial-pos1), its TORQUE negated in a temporary copy: it stops;
    declared with torque_sign = -1 its per-side compliances are the original's, declared as a
    reversed angle instead the loop reads mirrored, its + and − sides swapped."""
    from torsionfit.metrics import campaign_metrics

    text = _measured_copy_negated(tmp_path, "TORQUE")
    with pytest.raises(InputError, match=r"flip.csv: column 'POSITION' falls as column 'TORQUE' rises.*torque_sign"):
        load_campaign(tmp_path / "flip.toml")

    def sides(declared: str) -> tuple[float, float]:
        (tmp_path / "flip.toml").write_text(text.replace('kind = "hysteresis"', f'kind = "hysteresis"\n{declared} = -1'))
        m = campaign_metrics(load_campaign(tmp_path / "flip.toml"))["runs"][0]["metrics"]
        return m["compliance_loading_pos"]["value"], m["compliance_loading_neg"]["value"]

    m = campaign_metrics(load_campaign(EXAMPLES / "split-pccf-initial-pos1.toml"))["runs"][0]["metrics"]
    pos, neg = m["compliance_loading_pos"]["value"], m["compliance_loading_neg"]["value"]
    assert abs(pos - neg) > 0.05 * pos  # the sides differ on this loop, so a swap shows
    assert sides("torque_sign") == pytest.approx((pos, neg), rel=1e-9)
    assert sides("angle_sign") == pytest.approx((neg, pos), rel=1e-6)


# ----------------------------------------------------------------------------- TE direction


def test_te_direction_against_the_declared_one_is_caught():
    rising = np.radians(np.linspace(0.0, 720.0, 721))
    with pytest.warns(PlausibilityWarning, match=r"f\.csv: column 'phi' decreases .* direction = 'forward'"):
        check_te_direction(rising[::-1], +1, "f.csv", "phi")
    with pytest.warns(PlausibilityWarning, match=r"increases .* direction = 'backward'"):
        check_te_direction(rising, -1, "f.csv", "phi")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_te_direction(rising, +1, "f.csv", "phi")
        check_te_direction(np.mod(rising, 2 * math.pi), +1, "f.csv", "phi")  # wrapped at 360°
        check_te_direction(np.mod(rising, 2 * math.pi)[::-1], -1, "f.csv", "phi")


def test_te_direction_of_a_campaign_file(tmp_path):
    folder = tmp_path / "te"
    shutil.copytree(DATA / "paper-large", folder)
    manifest = folder / "campaign.toml"
    text = manifest.read_text()
    manifest.write_text(text.replace('file = "te-5rpm-380Nm-fw.csv"\nspeed_rpm = 5.0\ntorque_Nm = 380.0\n'
                                     'direction = "forward"', 'file = "te-5rpm-380Nm-fw.csv"\nspeed_rpm = 5.0\n'
                                     'torque_Nm = 380.0\ndirection = "backward"'))
    found = plausibility_warnings(manifest)
    assert len(found) == 1
    assert "te-5rpm-380Nm-fw.csv: column 'output_angle_deg' increases" in found[0]


# ----------------------------------------------------------------------------- CLI


def test_cli_prints_each_warning_on_one_line(tmp_path, capsys):
    path = without_resolution(relabelled(tmp_path, "paper-large", "angle_arcmin", "angle_deg"))
    assert main(["metrics", str(path), "--json"]) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("torsionfit metrics: warning: ")]
    assert len(lines) == 3 and all("angle_deg" in line for line in lines)
    assert "PlausibilityWarning" not in err and "warnings.warn" not in err


def test_cli_stops_with_one_line_when_the_angle_unit_is_contradicted(tmp_path, capsys):
    path = relabelled(tmp_path, "paper-large", "angle_arcmin", "angle_deg")
    assert main(["metrics", str(path), "--json"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith("torsionfit metrics: error: ") and "declare its unit arcmin" in err[0]


# ----------------------------------------------------------------------------- decimal comma


def test_decimal_comma_in_a_cell_gets_a_hint(tmp_path):
    path = tmp_path / "bench.csv"
    path.write_text("time_s;torque_Nm;angle_arcmin\n0;1.5;0.1\n0.1;1,25;0.2\n")
    table = read_table(path, f"{path}")
    with pytest.raises(InputError, match=r"bench\.csv: column 'torque_Nm' line 3: expected a number, "
                                         r"got '1,25'; it looks like a decimal comma"):
        table.numbers("torque_Nm")


def test_decimal_comma_in_a_comma_separated_file_gets_a_hint(tmp_path):
    path = tmp_path / "bench.csv"
    path.write_text("time_s,torque_Nm,angle_arcmin\n0,1,5,0,1\n")
    with pytest.raises(InputError, match=r"bench\.csv: line 2 has 5 fields.*has 3; it looks like a decimal comma"):
        read_table(path, f"{path}")
    path.write_text("a,b,c\n1,2\n")  # too few fields: no decimal comma to blame
    with pytest.raises(InputError) as info:
        read_table(path, f"{path}")
    assert "decimal comma" not in str(info.value)


# ----------------------------------------------------------------------------- errors name the file


def test_metric_errors_name_the_run_file(write_files, capsys):
    """'no full loop' and 'the angle does not grow with torque' name the file to open (arrays given
directly: the manifest's reader stops a reversed angle first)."""
    from torsionfit.metrics import hysteresis_metrics

    t = np.linspace(0.0, 40.0, 801)
    tau = 100.0 * np.sin(2 * np.pi * t / 20.0)
    rows = "\n".join(f"{a:.9g},{b:.9g},{c:.9g}" for a, b, c in zip(t, tau, -tau / 20.0))
    path = write_files({"campaign.toml": '[reducer]\nname = "u"\nrated_torque_Nm = 100.0\n'
                                         '[[runs]]\nname = "h"\nkind = "hysteresis"\nfile = "h.csv"\nangle_sign = -1\n',
                        "h.csv": "# SYNTHETIC\ntime_s,torque_Nm,angle_arcmin\n" + rows + "\n"})
    (run,) = load_campaign(path).runs  # read with its sign declared; the arrays reversed below
    reversed_run = type(run)(name="h", time_s=t, torque_Nm=tau, angle_rad=-run.angle_rad, source=run.source)
    with pytest.raises(InputError, match=r"hysteresis run 'h' \(file .*h\.csv\): the angle does not grow"):
        hysteresis_metrics(reversed_run, 100.0)
    one_sided = type(run)(name="h", time_s=t, torque_Nm=np.abs(tau), angle_rad=np.abs(tau) * ARCMIN,
                          source=run.source)
    with pytest.raises(InputError, match=r"hysteresis run 'h' \(file .*h\.csv\): no full loop found"):
        hysteresis_metrics(one_sided, 100.0)
    assert main(["metrics", str(path)]) == 0
    # the file read without its sign stops at reading, in one line naming the file and column
    path.write_text(path.read_text().replace("angle_sign = -1\n", ""))
    assert main(["metrics", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "h.csv: column 'angle_arcmin' falls" in err, err
