"""Closing the loop: the effects catalog, residual signatures, and the diagnosis (DESIGN §3)."""

from ._catalog import CATALOG as CATALOG, Effect as Effect, GapRelays as GapRelays
from ._context import FitContext as FitContext, RunView as RunView, fit_context as fit_context
from ._loop import (
    Diagnosis as Diagnosis,
    DiagnoseOptions as DiagnoseOptions,
    Fitted as Fitted,
    Step as Step,
    diagnose as diagnose,
    fit_with as fit_with,
)
from ._signature import Evidence as Evidence, regression_evidence as regression_evidence
from ._report import diagnose_json as diagnose_json, summary_text as summary_text, write_diagnosis as write_diagnosis
