"""scripts/measured_smc.py's page: SMC against the split normal on measured loops (the fits
themselves run by the script; here its table from rows of the shape it writes)."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from torsionfit._provenance import environment

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
_spec = importlib.util.spec_from_file_location("_measured_smc", ROOT / "scripts" / "measured_smc.py")
ms = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ms)


def _entry(play, slope, off, **extra):
    return {"seconds": 30.0, "converged": extra.pop("converged", True), "reason": extra.pop("reason", ""), "off_data": off,
            "metrics": {"play": {"mean": play[0], "hdi95": play[1:], "unit": "arcmin", "data": 12.2},
                        "stiffness_loading": {"mean": slope[0], "hdi95": slope[1:], "unit": "Nm/arcmin", "data": 0.1776}},
            **extra}


def test_the_page_sets_both_samplers_side_by_side_and_names_a_run_that_did_not_mix():
    smc = dict(smc_betas=[0.1, 0.5, 1.0], smc_moves=[100, 100, 100], smc_acceptance=[0.23] * 3,
               smc_correlation_max=0.62, approximation_pareto_k=1.8, converged=False,
               reason="the particles did not forget their start within 100 moves at stage(s) 1, 2, 3")
    row = {"unit": "split-pccf-preload2-pos5", "environment": environment(),
           "laplace": _entry((10.8, 10.5, 11.3), (0.1829, 0.1824, 0.1835), ["compliance_loading_neg"], pareto_k=1.87),
           "smc": _entry((10.5, 8.3, 12.6), (0.1820, 0.1770, 0.1878), [], **smc)}
    text = ms.markdown([row], 1000)
    line = next(l for l in text.splitlines() if l.startswith("| split-pccf-preload2-pos5"))
    assert "| 1.80 |" in line and "0.182 (0.177–0.1878)" in line and "0.1829 (0.1824–0.1835)" in line
    assert "| compliance_loading_neg / none |" in line and "| 3 | 100, 100, 100 | 8, one step | 0.62 | False |" in line
    assert "split-pccf-preload2-pos5: the particles did not forget their start" in text
    assert "Computed with Python" in text and "REAL" in text


def test_a_loops_row_is_reused_only_with_the_same_particles_and_seed(tmp_path):
    """Each loop's row is written as it is done; a rerun reuses it only when it was made the same way."""
    path = ms._row_path(tmp_path, "split-pccf-initial-pos1")
    path.parent.mkdir(parents=True)
    path.write_text('{"unit": "split-pccf-initial-pos1", "particles": 500, "seed": 0}')
    assert ms._done_row(tmp_path, "split-pccf-initial-pos1", 500, 0)["unit"] == "split-pccf-initial-pos1"
    assert ms._done_row(tmp_path, "split-pccf-initial-pos1", 1000, 0) is None
    assert ms._done_row(tmp_path, "split-pccf-initial-pos1", 500, 1) is None
    assert ms._done_row(tmp_path, "split-pccf-initial-pos5", 500, 0) is None
    assert ms._done_row(tmp_path, "split-pccf-initial-pos1", 500, 0, optima_mixture=True) is None
    assert ms._done_row(tmp_path, "split-pccf-initial-pos1", 500, 0, gap_prior_from_crossings=True) is None
    assert ms._done_row(tmp_path, "split-pccf-initial-pos1", 500, 0, final_max_moves=300) is None
    assert ms._done_row(tmp_path, "split-pccf-initial-pos1", 500, 0, max_moves=300) is None


def test_a_run_with_the_gap_prior_from_the_crossings_is_its_own_and_says_so(tmp_path):
    path = ms._row_path(tmp_path, "split-pccf-preload1-pos1")
    path.parent.mkdir(parents=True)
    path.write_text('{"unit": "split-pccf-preload1-pos1", "particles": 500, "seed": 0, "gap_prior_from_crossings": true}')
    assert ms._done_row(tmp_path, "split-pccf-preload1-pos1", 500, 0) is None
    assert ms._done_row(tmp_path, "split-pccf-preload1-pos1", 500, 0, gap_prior_from_crossings=True) is not None
    row = {"unit": "split-pccf-preload1-pos1", "environment": environment(),
           "laplace": _entry((10.8, 10.5, 11.3), (0.1829, 0.1824, 0.1835), []),
           "smc": _entry((10.5, 8.3, 12.6), (0.1820, 0.1770, 0.1878), [], smc_betas=[0.5, 1.0], smc_moves=[5, 9],
                         smc_acceptance=[0.6, 0.6], smc_correlation_max=0.05, approximation_pareto_k=1.0)}
    assert "--gap-prior-from-crossings" in ms.markdown([row], 500, gap_prior_from_crossings=True)
    assert "--gap-prior-from-crossings" not in ms.markdown([row], 500)


def test_a_run_from_the_optima_mixture_says_so_and_lists_each_loops_weights(tmp_path):
    """Rows started from the mixture over the optima are their own: not reused for a run from the
    split normal, nor the other way round; the page names the start and the weights it kept."""
    path = ms._row_path(tmp_path, "split-pccf-initial-pos6")
    path.parent.mkdir(parents=True)
    path.write_text('{"unit": "split-pccf-initial-pos6", "particles": 500, "seed": 0, "optima_mixture": true}')
    assert ms._done_row(tmp_path, "split-pccf-initial-pos6", 500, 0) is None
    assert ms._done_row(tmp_path, "split-pccf-initial-pos6", 500, 0, optima_mixture=True) is not None
    row = {"unit": "split-pccf-initial-pos6", "environment": environment(), "optima_mixture": True,
           "laplace_optima": [{"weight": 0.86}, {"weight": 0.08}, {"weight": 0.06}],
           "laplace": _entry((10.8, 10.5, 11.3), (0.1829, 0.1824, 0.1835), []),
           "smc": _entry((10.5, 8.3, 12.6), (0.1820, 0.1770, 0.1878), [], smc_betas=[0.5, 1.0], smc_moves=[5, 9],
                         smc_acceptance=[0.6, 0.6], smc_correlation_max=0.05, approximation_pareto_k=1.0)}
    text = ms.markdown([row], 500, optima_mixture=True)
    assert "--optima-mixture" in text and "split-pccf-initial-pos6: the mixture's weights 0.86, 0.08, 0.06" in text
    assert "--optima-mixture" not in ms.markdown([row], 500)


def test_a_loop_whose_particles_sat_in_separated_modes_says_where_and_with_what_shares():
    smc = dict(smc_betas=[0.5, 1.0], smc_moves=[12, 40], smc_acceptance=[0.6, 0.6], smc_correlation_max=0.08,
               approximation_pareto_k=1.1, smc_modes=[1, 2], smc_mode_shares=[0.31, 0.69])
    row = {"unit": "split-pccf-initial-pos6", "environment": environment(),
           "laplace": _entry((10.8, 10.5, 11.3), (0.1829, 0.1824, 0.1835), []),
           "smc": _entry((10.5, 8.3, 12.6), (0.1820, 0.1770, 0.1878), [], **smc)}
    text = ms.markdown([row], 500)
    assert "split-pccf-initial-pos6: the particles sat in separated modes the moves do not cross at stage(s) 2" in text
    assert "2 modes, shares 0.31, 0.69" in text
    row["smc"]["smc_modes"] = [1, 1]
    assert "separated modes the moves do not cross" not in ms.markdown([row], 500)


def test_a_row_says_which_hmc_kernel_made_it():
    """Rows made before the drawn steps carry no kernel: 'one step'; rows made with them their
    mean leapfrog steps per move."""
    row = {"unit": "split-pccf-initial-pos6", "laplace": {}, "smc": {"smc_leapfrog_steps": [12.0, 30.0]}}
    assert ms.kernel_text(row) == "8, one step"
    row["kernel"] = ms.kernel_settings()
    assert ms.kernel_text(row) == "21, drawn steps" and row["kernel"]["step_spread"] == 30.0
    row["final_max_moves"] = 300  # a longer last stage is the row's own and says so
    assert ms.kernel_text(row) == "21, drawn steps, 300 moves allowed at β = 1"
    row["max_moves"] = 300  # so does a longer budget at every stage; the last gets at least as many
    assert ms.kernel_text(row) == "21, drawn steps, 300 moves allowed at every stage"
    row["final_max_moves"] = 500
    assert ms.kernel_text(row) == "21, drawn steps, 300 moves allowed at every stage, 500 moves allowed at β = 1"


def test_the_departure_lists_the_coordinates_the_particles_moved_most_first_in_the_split_normals_sd():
    rng = np.random.default_rng(0)
    split = rng.normal(size=(4000, 3))
    particles = rng.normal(size=(500, 3)) * [1.0, 3.0, 1.0] + [0.0, 0.0, -6.0]
    rows = ms.departure(split, particles, ["gap", "preload_lift_torque", "gap_hold_torque"])
    assert rows[0]["name"] == "gap_hold_torque" and rows[0]["shift_sd"] == pytest.approx(-6.0, abs=0.3)
    assert next(r for r in rows if r["name"] == "preload_lift_torque")["width_ratio"] == pytest.approx(3.0, rel=0.1)
    row = {"unit": "split-pccf-initial-pos6", "environment": environment(), "departure": rows,
           "laplace": _entry((10.8, 10.5, 11.3), (0.1829, 0.1824, 0.1835), []),
           "smc": _entry((10.5, 8.3, 12.6), (0.1820, 0.1770, 0.1878), [], smc_betas=[1.0], smc_moves=[5],
                         smc_acceptance=[0.6], smc_correlation_max=0.05, approximation_pareto_k=1.0)}
    assert "where the particles depart most from the split normal" in ms.markdown([row], 500)
    assert f"gap_hold_torque {rows[0]['shift_sd']:+.1f} sd" in ms.markdown([row], 500)


def test_progress_lines_are_torsionfits_own_named_by_the_loop_and_leave_other_libraries_quiet(capsys):
    import logging

    before = logging.getLogger("torsionfit"), logging.getLogger().level
    try:
        ms._progress_lines("loop-a")
        ms._progress_lines("loop-b")  # a second loop in the same process replaces the first's name
        logging.getLogger("torsionfit.sample._smc").info("stage 1")
        logging.getLogger("arviz_stats.base.stats_utils").info("Shape validation failed")
        err = capsys.readouterr().err
        assert err.splitlines() == ["loop-b: stage 1"]
    finally:
        logger = before[0]
        for handler in list(logger.handlers):
            logger.removeHandler(handler)
        logger.setLevel(logging.NOTSET)


def test_the_page_is_the_folders_a_run_of_one_loop_keeps_the_others_rows(tmp_path, monkeypatch, capsys):
    """The page is written from every row saved in the folder, whichever run made it: a run of one
    loop adds its row; --render writes the page again without fitting; rows of other particle
    counts are named as such in the header."""
    smc = dict(smc_betas=[0.5, 1.0], smc_moves=[5, 9], smc_acceptance=[0.6, 0.6], smc_correlation_max=0.05,
               approximation_pareto_k=1.0)
    for unit, particles in (("split-pccf-initial-pos1", 500), ("split-pccf-initial-pos5", 1000)):
        row = {"unit": unit, "environment": environment(), "particles": particles, "seed": 0,
               "laplace": _entry((10.8, 10.5, 11.3), (0.1829, 0.1824, 0.1835), []),
               "smc": _entry((10.5, 8.3, 12.6), (0.1820, 0.1770, 0.1878), [], **smc)}
        path = ms._row_path(tmp_path, unit)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(ms.json.dumps(row))
    assert ms.main(["-o", str(tmp_path), "--render"]) == 0
    text = (tmp_path / "smc.md").read_text()
    assert "| split-pccf-initial-pos1 |" in text and "| split-pccf-initial-pos5 |" in text
    assert "SMC: 500–1000 (each row its own) particles" in text
    assert len(ms.json.loads((tmp_path / "smc.json").read_text())["units"]) == 2
    # a run naming only one loop whose row is saved reuses it and keeps the other's on the page
    monkeypatch.setattr(ms.mv, "DATA", tmp_path)  # present, so the run goes on to the rows
    assert ms.main(["--units", "split-pccf-initial-pos1", "-o", str(tmp_path), "--particles", "500"]) == 0
    assert "| split-pccf-initial-pos5 |" in (tmp_path / "smc.md").read_text()


def test_render_of_an_empty_folder_says_so_and_a_run_must_name_loops(tmp_path, capsys):
    assert ms.main(["-o", str(tmp_path), "--render"]) == 2
    assert "no saved rows" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        ms.main(["-o", str(tmp_path)])
    assert "--units: name the loops" in capsys.readouterr().err


def test_each_loop_and_settings_keeps_its_own_smc_checkpoint_in_the_output_folder(tmp_path):
    from torsionfit.report import FitOptions, smc_checkpoint_path

    base = dict(unit="split-pccf-preload2-pos1", particles=500, seed=0, optima_mixture=False,
                gap_prior_from_crossings=False, final_max_moves=300)
    path = ms._chain_path(tmp_path, **base)
    checkpoint = Path(smc_checkpoint_path(FitOptions(backend_path=str(path))))
    assert checkpoint.parent == tmp_path / "checkpoints" and checkpoint.name.startswith("split-pccf-preload2-pos1-")
    assert checkpoint.suffix == ".npz"
    # a run of other settings neither resumes nor overwrites it
    others = [dict(base, unit="split-pccf-preload3-pos5"), dict(base, particles=1000), dict(base, seed=1),
              dict(base, optima_mixture=True), dict(base, gap_prior_from_crossings=True), dict(base, final_max_moves=100),
              dict(base, max_moves=300)]
    assert len({path, *(ms._chain_path(tmp_path, **o) for o in others)}) == 1 + len(others)
    assert smc_checkpoint_path(FitOptions()) is None  # no chain kept: no checkpoint
