"""Everything the paper's figures and tables are made from — the bundled SYNTHETIC campaigns,
their data-only metrics, the model fits, the operating grids and their polynomials, the worn
unit and the acceptance decisions — each computed once, on first use, with explicit seeds."""

import dataclasses
import time
import zlib
from pathlib import Path

import numpy as np

from .._errors import InputError
from ..accept import accept_campaign, bind_to_campaign, operating_envelope, parse_spec
from ..bench import load_bench, simulate
from ..io import load_campaign
from ..metrics import campaign_metrics
from ._choice import fit_with_fallback
from ._fault import worn_bench
from ._grid import grid_axes, simulate_grid
from ._polynomial import select_polynomial
from ._posterior import kd_draws, quasi_static_rate, run_component_draws, secant_draws
from ._published import CAMPAIGNS
from ._settings import PaperSettings

#: Fig. 19's requirement on the small reducer: K_d ≥ this over the region below (N·m/°)
KD_REQUIRED_NM_PER_DEG = 0.2
REGION_TORQUE_FRACTION = (0.6, 1.0)
P_ACCEPT = 0.95


def default_data_dir() -> Path:
    """``data/`` of the source checkout this package runs from."""
    return Path(__file__).resolve().parents[3] / "data"


def derived_seed(seed: int, tag: str) -> int:
    """A seed for one random task (``tag``) derived from the run's ``seed``."""
    return int(np.random.SeedSequence([int(seed), zlib.crc32(tag.encode())]).generate_state(1)[0])


class Reproduction:
    """Lazy holder of the reproduction's ingredients for ``settings``; ``data_dir`` holds the
    bundled campaigns (``paper-small/``, ``paper-large/``). ``progress(text)`` hears of each
    long step; ``timings`` records their seconds."""

    def __init__(self, settings: PaperSettings, data_dir=None, progress=None):
        self.settings = settings
        self.data_dir = Path(data_dir) if data_dir is not None else default_data_dir()
        for name in CAMPAIGNS.values():
            if not (self.data_dir / name / "campaign.toml").is_file():
                raise InputError(f"{self.data_dir / name / 'campaign.toml'}: bundled campaign not found; "
                                 f"give the folder holding paper-small/ and paper-large/ with --data")
        self.show_progress = progress is not None
        self.progress = progress or (lambda text: None)
        self.timings: dict[str, float] = {}
        self._cache: dict = {}

    def _once(self, key, make):
        if key not in self._cache:
            self.progress(f"{key[0]} {' '.join(str(k) for k in key[1:])}".strip())
            t0 = time.perf_counter()
            self._cache[key] = make()
            self.timings[" ".join(str(k) for k in key)] = time.perf_counter() - t0
        return self._cache[key]

    # --- data -------------------------------------------------------------------------------
    def campaign(self, name: str):
        """The bundled campaign ``name`` ("paper-small" or "paper-large")."""
        return self._once(("load", name), lambda: load_campaign(self.data_dir / name / "campaign.toml"))

    def bench(self, name: str):
        """The virtual bench that made campaign ``name``."""
        return self._once(("bench", name), lambda: load_bench(self.data_dir / name / "bench.toml"))

    def data_metrics(self, name: str) -> dict:
        """``{run name: metrics}`` of campaign ``name`` from the data alone (``torsionfit metrics``)."""
        return self._once(("metrics", name), lambda: {
            r["name"]: r["metrics"] for r in campaign_metrics(self.campaign(name))["runs"]})

    # --- model ------------------------------------------------------------------------------
    def fitted_runs(self, campaign):
        """The runs fitted: all, or (quick) the slowest loop and every TE run."""
        if self.settings.all_loops or not campaign.hysteresis_runs:
            return campaign
        slowest = min(campaign.hysteresis_runs, key=lambda r: r.loading_rate_Nm_per_s or 0.0)
        return dataclasses.replace(campaign, runs=(slowest,) + campaign.te_runs)

    def model_effects(self, name: str) -> dict:
        """The model's extensions for campaign ``name``: its bench's effects, but speed
        dependence by the compliance alone — with TE runs at one load in one direction, viscous
        friction, the two compliance terms and the shared TE zero are four unknowns for three
        TE levels, and the MAP and the sampler wander along the direction the data cannot see."""
        effects = dict(self.bench(name).effects)
        if isinstance(effects.get("speed_dependence"), dict):
            effects["speed_dependence"] = {**effects["speed_dependence"], "viscous": False}
        return effects

    def _fit(self, campaign, options_name: str, tag: str):
        """Fit ``campaign`` with the model of bundled campaign ``options_name`` (:meth:`model_effects`):
        the sampled posterior when the settings' sampler converges within its budget, else the
        Laplace approximation (:func:`fit_with_fallback`)."""
        options = self.settings.fit_options(self.model_effects(options_name), options_name, self.show_progress)
        return fit_with_fallback(self.fitted_runs(campaign), options, seed=derived_seed(self.settings.seed, tag))

    def fit(self, name: str):
        """The model fitted to campaign ``name``; the model's extensions are the bench's effects."""
        return self._once(("fit", name), lambda: self._fit(self.campaign(name), name, f"fit {name}"))

    def run_components(self, name: str) -> dict:
        """The parts of the angle along every fitted run of ``name``, by run name, over the
        settings' band draws (:func:`run_component_draws`)."""
        return self._once(("components", name), lambda: run_component_draws(
            self.fit(name), self.settings.band_draws, derived_seed(self.settings.seed, f"bands {name}")))

    def secant_rates(self, name: str) -> tuple[float, ...]:
        """The loading rates (N·m/s) of ``name``'s loops, then the quasi-static rate (τ̇ → 0)."""
        fit = self.fit(name)
        return tuple(r.loading_rate_Nm_per_s for r in self.campaign(name).hysteresis_runs) + (quasi_static_rate(fit),)

    def secants(self, name: str) -> np.ndarray:
        """(draws, rates) the model's K_s (N·m/arcmin) at :meth:`secant_rates`."""
        return self._once(("secants", name), lambda: secant_draws(self.fit(name), self.secant_rates(name)))

    def zero_rate_and_speed(self, name: str) -> dict:
        """Eq. (25): posterior draws (N·m/arcmin) of the model's K_s at τ̇ → 0 (``"ks0"``) and
        K_d at v → 0, forward (``"kd0"``), both at T_r."""
        def make():
            fit = self.fit(name)
            rated = fit.campaign.reducer.rated_torque_Nm
            return {"ks0": self.secants(name)[:, -1], "kd0": kd_draws(fit, rated, 0.0)[:, 0]}
        return self._once(("limits", name), make)

    # --- all operating conditions ----------------------------------------------------------
    def grid_axes(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        s = self.settings
        return grid_axes(self.campaign(name).reducer.rated_torque_Nm, s.grid_max_speed_rpm, s.grid_torques, s.grid_speeds)

    def grid(self, name: str):
        """TE over the torque × speed grid on the virtual bench of ``name``, data-only (``OperatingGrid``)."""
        return self._once(("grid", name), lambda: simulate_grid(
            self.bench(name), *self.grid_axes(name), seed=derived_seed(self.settings.seed, f"grid {name}")))

    def polynomial(self, name: str, quantity: str):
        """H of Eqs. (26)–(28): the polynomial of TE(180°) (``quantity="kd"``) or of the
        revolution-mean TE (``"kt"``) over the grid of ``name``, degrees by BIC."""
        def make():
            g = self.grid(name)
            te = g.te_180_arcmin if quantity == "kd" else g.te_mean_arcmin
            t, v = g.points()
            return select_polynomial(t, v, te.ravel(), unit="arcmin")
        if quantity not in ("kd", "kt"):
            raise InputError(f"polynomial quantity must be 'kd' or 'kt', got {quantity!r}")
        return self._once(("polynomial", name, quantity), make)

    # --- Fig. 19: a worn unit and the acceptance decision ----------------------------------
    def worn_campaign(self):
        """The worn small reducer (:func:`worn_bench`), simulated with the bundled runs."""
        seed = derived_seed(self.settings.seed, "worn unit")
        return self._once(("simulate", "worn"), lambda: simulate(worn_bench(self.bench("paper-small"), seed)).campaign)

    def worn_fit(self):
        return self._once(("fit", "worn"), lambda: self._fit(self.worn_campaign(), "paper-small", "fit worn"))

    def spec(self):
        """Fig. 19's requirement: K_d ≥ 0.2 N·m/° over 0.6–1.0 T_r × the grid's speeds."""
        rated = self.campaign("paper-small").reducer.rated_torque_Nm
        lo, hi = (f * rated for f in REGION_TORQUE_FRACTION)
        return parse_spec({
            "label": "SYNTHETIC example requirement for Fig. 19", "p_accept": P_ACCEPT,
            "requirement": [{"metric": "kd", "name": "K_d over the operating region", "min": KD_REQUIRED_NM_PER_DEG,
                             "unit": "Nm/deg", "torque_Nm": [lo, hi], "speed_rpm": [1.0, self.settings.grid_max_speed_rpm]}],
        }, "Fig. 19 spec")

    def acceptance(self, unit: str):
        """(``Decision``, ``Envelope``) of the ``"normal"`` (bundled) or ``"worn"`` small reducer
        against :meth:`spec`, from its fit; the envelope over the grid's torque × speed range."""
        def make():
            fit = self.fit("paper-small") if unit == "normal" else self.worn_fit()
            spec = self.spec()
            result = accept_campaign(fit.campaign, spec, fit.options, envelope=False, fit=fit)
            _, derived = bind_to_campaign(spec, fit.campaign, fit.options)
            torque, _ = self.grid_axes("paper-small")
            axes = (np.linspace(torque[0], torque[-1], 25), np.linspace(1.0, self.settings.grid_max_speed_rpm, 19))
            return result.decision, operating_envelope(derived, fit.metric_values, result.bound[0], spec.p_accept, *axes)
        if unit not in ("normal", "worn"):
            raise InputError(f"unit must be 'normal' or 'worn', got {unit!r}")
        return self._once(("accept", unit), make)
