"""Write loop_export.csv: a SYNTHETIC hysteresis loop in the shape of a bench export.

The loop comes from the virtual bench (tests/benches/rv_small_base.toml: a cycloidal reducer,
380 N·m rated, 108 N·m/arcmin, the paper's five-step protocol at 5 N·m/s). It is written the way
bench software often writes: semicolon separated, its own column names, time in milliseconds,
angle in degrees, a status column whose first rows are the bench's set-up, not data.

    python docs/examples/my-bench/make_export.py [-o FOLDER]
"""

import argparse
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
BENCH = HERE.parents[2] / "tests" / "benches" / "rv_small_base.toml"
SETUP_ROWS = 20  # rows the bench marks "SETUP" before its data


def write_export(folder: Path, seed: int = 1) -> Path:
    """Simulate the bench's hysteresis run and write it as ``folder/loop_export.csv``."""
    from torsionfit.bench import load_bench, simulate
    from torsionfit.io import HysteresisRun

    run = next(r for r in simulate(load_bench(BENCH), seed=seed).campaign.runs if isinstance(r, HysteresisRun))
    status = np.where(np.arange(len(run.time_s)) < SETUP_ROWS, "SETUP", "OK")
    path = Path(folder) / "loop_export.csv"
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8") as handle:
        handle.write("# SYNTHETIC data from the torsionfit virtual bench (tests/benches/rv_small_base.toml)\n")
        handle.write("Time [ms];Torque [Nm];Output angle [deg];Status\n")
        for t, tau, theta, s in zip(run.time_s * 1e3, run.torque_Nm, np.degrees(run.angle_rad), status):
            handle.write(f"{t:.3f};{tau:.4f};{theta:.7f};{s}\n")
    return path


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=HERE, help="folder for loop_export.csv (default: here)")
    print(f"wrote {write_export(parser.parse_args().output)}")
