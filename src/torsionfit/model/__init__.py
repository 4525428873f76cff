"""The differentiable forward model (DESIGN §1): small equinox modules, pure functions of
(parameters, data). Parameters are a dict of SI values keyed by ``Parameter.name``."""

from ._backlash import (
    AbstractBacklash as AbstractBacklash,
    ClosedGapBacklash as ClosedGapBacklash,
    FrictionClosureBacklash as FrictionClosureBacklash,
    HeldGapBacklash as HeldGapBacklash,
    NoBacklash as NoBacklash,
    RELAY_FLANK_SHARE as RELAY_FLANK_SHARE,
    PreloadedBacklash as PreloadedBacklash,
    RelayGapBacklash as RelayGapBacklash,
    ResidualPlayBacklash as ResidualPlayBacklash,
    SmoothBacklash as SmoothBacklash,
    SteppedBacklash as SteppedBacklash,
)
from ._campaign_model import COMPONENTS as COMPONENTS, RUN_START_STATES as RUN_START_STATES, CampaignModel as CampaignModel
from ._compliance import (
    AbstractCompliance as AbstractCompliance,
    AsymmetricCompliance as AsymmetricCompliance,
    LinearCompliance as LinearCompliance,
    PowerLawCompliance as PowerLawCompliance,
    PreloadedCompliance as PreloadedCompliance,
    ThreeSegmentCompliance as ThreeSegmentCompliance,
)
from ._creep import Creep as Creep
from ._effects import model_with_effects as model_with_effects
from ._friction import (
    AbstractFriction as AbstractFriction,
    DahlFriction as DahlFriction,
    MaxwellSlipFriction as MaxwellSlipFriction,
)
from ._gap_lag import GapLag as GapLag
from ._series import SeriesCompliance as SeriesCompliance
from ._play import play_scan as play_scan
from ._inputs import (
    HysteresisInput as HysteresisInput,
    TEInput as TEInput,
    hysteresis_input as hysteresis_input,
    te_input as te_input,
)
from ._kinematic import KinematicHarmonics as KinematicHarmonics
from ._parameter import Parameter as Parameter
from ._recurrence import (
    affine_scan as affine_scan,
    first_order_lag as first_order_lag,
    resolve_scan_method as resolve_scan_method,
)
from ._speed import SpeedDependence as SpeedDependence
from ._temperature import TemperatureDependence as TemperatureDependence
