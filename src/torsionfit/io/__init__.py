"""Campaign files: TOML manifest + CSV / CSV.gz runs (DESIGN §5.1)."""

from ._campaign import (
    Campaign as Campaign,
    HysteresisRun as HysteresisRun,
    Instrument as Instrument,
    Reducer as Reducer,
    Run as Run,
    TransmissionErrorRun as TransmissionErrorRun,
    reference_temperature_C as reference_temperature_C,
)
from ._decimate import decimate as decimate
from ._manifest import load_campaign as load_campaign, write_campaign as write_campaign
from ._plausibility import PlausibilityWarning as PlausibilityWarning
