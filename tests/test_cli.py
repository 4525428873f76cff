"""Command line: --help, --version, simulate, metrics, one-line errors with a non-zero exit, the
same --quiet on every command, progress, Ctrl-C, provenance of the JSON outputs (a fit's
progress and provenance: tests/test_report.py, whose fits compile the same programs)."""

import json
import logging
import subprocess
import sys
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import torsionfit
from torsionfit._provenance import command_line, environment
from torsionfit.accept import ExtrapolationWarning
from torsionfit.cli import EXIT_INPUT_ERROR, EXIT_INTERRUPTED, _one_line_warnings, build_parser, main
from torsionfit.sample import run_sampler

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


# --- the same options everywhere, --version, provenance -----------------------------------------
COMMANDS = ("simulate", "metrics", "fit", "diagnose", "accept", "batch", "paper")


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"torsionfit {torsionfit.__version__}"


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_quiet_and_keeps_no_progress_as_a_hidden_alias(command):
    parser = build_parser()
    sub = parser._subparsers._group_actions[0].choices[command]
    assert "--quiet" in sub.format_help() and "--no-progress" not in sub.format_help()
    required = {"simulate": ["b.toml", "-o", "x"], "metrics": ["c.toml"], "fit": ["c.toml", "-o", "x"],
                "diagnose": ["c.toml", "-o", "x"], "accept": ["c.toml", "--spec", "s.toml", "-o", "x"],
                "batch": ["f", "-o", "x"], "paper": ["-o", "x"]}[command]
    for flag in ("--quiet", "-q", "--no-progress"):
        assert parser.parse_args([command, *required, flag]).quiet
    assert not parser.parse_args([command, *required]).quiet


def test_metrics_has_no_seed_it_would_not_use(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["metrics", "c.toml", "--seed", "3"])
    assert exc.value.code == 2 and "--seed" in capsys.readouterr().err


def test_metrics_json_records_version_and_command_line(tmp_path, capsys):
    main(["simulate", str(BENCH), "-o", str(tmp_path / "c"), "--quiet"])
    capsys.readouterr()
    assert main(["metrics", str(tmp_path / "c"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["provenance"] == {"torsionfit_version": torsionfit.__version__, "seed": None,
                                 "command": f"torsionfit metrics {tmp_path / 'c'} --json",
                                 "environment": environment()}


def _noise_seen(tmp_path, monkeypatch, module, function: str, command: str, flag: list, read, part=lambda o: o.noise):
    """What ``read`` gives of the options' ``part`` (their noise options unless told) that
    ``command`` hands to ``module.function`` (stopped there)."""

    class Seen(Exception):
        pass

    def capture(campaign, options, *args, **kwargs):
        raise Seen(read(part(options)))

    main(["simulate", str(BENCH), "-o", str(tmp_path / "c"), "--quiet"])
    monkeypatch.setattr(module, function, capture)
    with pytest.raises(Seen) as seen:
        main([command, str(tmp_path / "c"), "-o", str(tmp_path / "out"), "--quiet", *flag])
    return seen.value.args[0]


@pytest.mark.parametrize("flag, ar1", [([], None), (["--ar1", "off"], False), (["--ar1", "on"], True)])
def test_diagnose_passes_its_noise_option_to_every_fit(tmp_path, monkeypatch, flag, ar1):
    import torsionfit.diagnose as diagnose_module

    assert _noise_seen(tmp_path, monkeypatch, diagnose_module, "diagnose", "diagnose", flag, lambda n: n.ar1) == ar1


@pytest.mark.parametrize("flag, dof", [([], None), (["--student-t", "4"], 4.0)])
def test_diagnose_passes_its_student_t_option_to_every_fit(tmp_path, monkeypatch, flag, dof):
    import torsionfit.diagnose as diagnose_module

    assert _noise_seen(tmp_path, monkeypatch, diagnose_module, "diagnose", "diagnose", flag,
                       lambda n: n.student_t_dof) == dof


@pytest.mark.parametrize("flag, robust", [([], True), (["--least-squares-signatures"], False)])
def test_diagnose_passes_its_signature_option(tmp_path, monkeypatch, flag, robust):
    import torsionfit.diagnose as diagnose_module

    assert _noise_seen(tmp_path, monkeypatch, diagnose_module, "diagnose", "diagnose", flag,
                       lambda robust_signatures: robust_signatures, part=lambda o: o.robust_signatures) is robust


@pytest.mark.parametrize("flag, checks", [([], (True, True)), (["--no-swap"], (True, False)),
                                          (["--no-backward"], (False, True))])
def test_diagnose_passes_its_backward_and_swap_options(tmp_path, monkeypatch, flag, checks):
    import torsionfit.diagnose as diagnose_module

    assert _noise_seen(tmp_path, monkeypatch, diagnose_module, "diagnose", "diagnose", flag,
                       lambda o: (o.backward, o.swap), part=lambda o: o) == checks


@pytest.mark.parametrize("flag, on", [([], False), (["--class-noise"], True)])
def test_fit_passes_the_class_noise_option(tmp_path, monkeypatch, flag, on):
    import torsionfit.report as report_module

    seen = _noise_seen(tmp_path, monkeypatch, report_module, "fit_campaign", "fit", flag, lambda n: n.cycle_class_noise)
    assert seen is on


def test_fit_passes_the_conditioning_option(tmp_path, monkeypatch):
    import torsionfit.report as report_module

    seen = _noise_seen(tmp_path, monkeypatch, report_module, "fit_campaign", "fit", ["--condition-first-excursions"],
                       lambda n: (n.first_excursion_conditioning, n.first_excursion_class))
    assert seen == (True, False)


def test_command_line_is_quoted_as_a_shell_takes_it_back():
    assert command_line(["fit", "my campaign/campaign.toml", "--with", "kinematic_error=[1, 2]"]) == \
        "torsionfit fit 'my campaign/campaign.toml' --with 'kinematic_error=[1, 2]'"


# --- progress and Ctrl-C --------------------------------------------------------------------------
def _gaussian_sampler_inputs(dim=2):
    problem = SimpleNamespace(dim=dim)
    start = SimpleNamespace(u=np.zeros(dim), cov=np.eye(dim), names=[f"p{i}" for i in range(dim)])
    return problem, start


def test_emcee_reports_steps_done_and_an_estimate_of_those_left(caplog):
    problem, start = _gaussian_sampler_inputs()
    caplog.set_level(logging.INFO, logger="torsionfit")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run_sampler(problem, start, seed=0, n_walkers=8, max_steps=300, check_every=100, min_steps=10_000,
                    progress=False, evaluate=lambda chunk: -0.5 * np.sum(np.asarray(chunk) ** 2, axis=1))
    lines = [r.getMessage() for r in caplog.records if r.name == "torsionfit.sample._emcee"]
    assert len(lines) == 3  # one per check, none converged (min_steps)
    assert lines[0].startswith("emcee: 100 steps of at most 300; τ_max ≈")
    assert all("more" in line for line in lines) and lines[-1].endswith("beyond the cap)")


def test_ctrl_c_in_the_sampler_is_not_a_page_of_walker_positions(capsys):
    """emcee's own wrapper printed every walker's position and a traceback on Ctrl-C."""
    problem, start = _gaussian_sampler_inputs()
    calls = []

    def evaluate(chunk):
        calls.append(1)
        if len(calls) > 5:
            raise KeyboardInterrupt
        return -0.5 * np.sum(np.asarray(chunk) ** 2, axis=1)

    with pytest.raises(KeyboardInterrupt):
        run_sampler(problem, start, seed=0, n_walkers=8, max_steps=100, progress=False, evaluate=evaluate)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""


@pytest.mark.parametrize("extra, says", [
    (["--save-chain"], "the same command with --resume continues it"),
    (["--save-chain", "--sampler", "smc"], "chain-smc.npz: the same command with --resume continues it"),
    ([], "no chain was kept (--save-chain keeps one that --resume continues)"),
])
def test_ctrl_c_during_a_fit_is_one_line_and_exit_130(tmp_path, capsys, monkeypatch, extra, says):
    import torsionfit.report

    main(["simulate", str(BENCH), "-o", str(tmp_path / "c"), "-q"])

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(torsionfit.report, "fit_campaign", interrupted)
    capsys.readouterr()
    assert main(["fit", str(tmp_path / "c"), "-o", str(tmp_path / "f"), *extra]) == EXIT_INTERRUPTED
    err = capsys.readouterr().err
    assert err.startswith("[fit] read ")  # progress before the interruption
    last = err.splitlines()[-1]
    assert last.startswith("torsionfit fit: interrupted; ") and says in last and "Traceback" not in err
    # the chain's folder exists before the sampler writes its first step into it
    assert (tmp_path / "f").is_dir() == bool(extra)
    assert main(["fit", str(tmp_path / "c"), "-o", str(tmp_path / "f"), "--quiet"]) == EXIT_INTERRUPTED
    assert capsys.readouterr().err.count("\n") == 1


def test_torsionfits_warnings_are_one_line(capsys):
    show = _one_line_warnings("accept")
    show(ExtrapolationWarning("'kd': the decision extrapolates the model (speed 0–30 rpm asked)"),
         ExtrapolationWarning, "x.py", 1)
    assert capsys.readouterr().err == "torsionfit accept: warning: 'kd': the decision extrapolates the model (speed 0–30 rpm asked)\n"
    # a plain UserWarning raised in torsionfit's code (the fit's notes) is one line too; one
    # raised elsewhere goes to Python's own display (here pytest's), not ours
    import torsionfit.report._pipeline as pipeline

    show = _one_line_warnings("fit")
    show(UserWarning("metrics not computed: play: ..."), UserWarning, pipeline.__file__, 811)
    assert capsys.readouterr().err == "torsionfit fit: warning: metrics not computed: play: ...\n"
    for elsewhere in ("/elsewhere/lib.py", "<string>"):
        show(UserWarning("from a library"), UserWarning, elsewhere, 3)
        assert "torsionfit fit" not in capsys.readouterr().err


@pytest.mark.parametrize("flag, wanted", [(["--sampler", "smc"], ("smc", 1000, 100, 100)),
                                          (["--sampler", "smc", "--smc-particles", "300"], ("smc", 300, 100, 100)),
                                          (["--sampler", "smc", "--smc-final-moves", "300"], ("smc", 1000, 100, 300)),
                                          (["--sampler", "smc", "--smc-moves", "300"], ("smc", 1000, 300, 100))])
def test_fit_passes_the_smc_sampler_and_its_particles(tmp_path, monkeypatch, flag, wanted):
    import torsionfit.report as report_module

    seen = _noise_seen(tmp_path, monkeypatch, report_module, "fit_campaign", "fit", flag,
                       lambda o: (o.sampler, o.smc_particles, o.smc_max_moves, o.smc_final_max_moves), part=lambda o: o)
    assert seen == wanted


def test_fit_refuses_a_last_smc_stage_shorter_than_the_others(capsys):
    with pytest.raises(SystemExit):
        main(["fit", "campaign.toml", "--sampler", "smc", "--smc-final-moves", "50"])
    assert "--smc-final-moves: expected at least 100 moves" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["fit", "campaign.toml", "--sampler", "smc", "--smc-moves", "0"])
    assert "--smc-moves: expected at least 1 moves (a stage moves its particles at least once)" in capsys.readouterr().err
