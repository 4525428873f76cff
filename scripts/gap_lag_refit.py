"""What the damped-gap extension does on the measured split loop of the diagnose trail.

REAL measured data (JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0; read from
../shared/data, nothing printed if it is absent). Refits split-pccf initial-pos1 at block means of
16, as ``scripts/diagnose_measured.py`` does, with the three-segment compliance the trail added
and then with ``gap_lag`` on top (from the first fit's optimum, as ``diagnose`` refits), and prints
for each: RMSE, MAP log density, the fitted AR(1) innovation sd and ρ, and the gap lag.

    .venv/bin/python scripts/gap_lag_refit.py
"""

import sys
from pathlib import Path

import jax.numpy as jnp

from torsionfit._x64 import in_float64
from torsionfit.diagnose._loop import DiagnoseOptions, fit_with
from torsionfit.io import decimate, load_campaign

ROOT = Path(__file__).resolve().parents[1]
MANIFEST = ROOT / "examples" / "cycloidal-jv" / "split-pccf-initial-pos1.toml"
ARCSEC_PER_RAD = 206264.80624709636


@in_float64
def main() -> int:
    if not (ROOT.parent / "shared" / "data" / "cycloidal-jv").is_dir():
        print("../shared/data/cycloidal-jv is absent: nothing to do")
        return 0
    campaign = decimate(load_campaign(MANIFEST), 16)
    options = DiagnoseOptions()
    base = {"stiffness_nonlinearity": "three_segment"}
    without = fit_with(campaign, base, options, 0)
    with_lag = fit_with(campaign, {**base, "gap_lag": True}, options, 0, warm=without)
    for name, fit in (("three-segment", without), ("three-segment + gap_lag", with_lag)):
        problem, u = fit.map_result.problem, jnp.asarray(fit.map_result.u)
        sigma, rho = problem.noise_values(u)
        lag = fit.map_result.values.get("gap_lag_time")
        print(f"{name:26s} RMSE {fit.rmse_arcsec:6.0f}″  log density {fit.map_result.log_density:9.1f}  "
              f"AR(1) innovation sd {float(sigma[0]) * ARCSEC_PER_RAD:5.0f}″, ρ {float(rho[0]):.3f}"
              + ("" if lag is None else f"  gap lag {float(lag):.1f} s"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
