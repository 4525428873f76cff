"""Acceptance decisions from the posterior (DESIGN §4, JCGM 106 style): spec files, probability
of conformance per requirement and jointly, accept / reject / indeterminate with the specific
risks, the operating envelope P(K_d(τ, v) ≥ K_req), and batches of units."""

from ._batch import (
    ERROR as ERROR,
    EXIT_UNIT_ERROR as EXIT_UNIT_ERROR,
    accept_folder as accept_folder,
    batch_exit_code as batch_exit_code,
    find_campaigns as find_campaigns,
    write_batch_table as write_batch_table,
)
from ._conformance import conformance as conformance, requirement_quantities as requirement_quantities
from ._decision import (
    ACCEPT as ACCEPT,
    EXIT_CODE as EXIT_CODE,
    INDETERMINATE as INDETERMINATE,
    REJECT as REJECT,
    Decision as Decision,
    decide as decide,
    decide_unit as decide_unit,
    risk_from_draws as risk_from_draws,
    risk_text as risk_text,
)
from ._envelope import (
    Envelope as Envelope,
    envelope_axes as envelope_axes,
    kd_worst_direction as kd_worst_direction,
    operating_envelope as operating_envelope,
    region_kd_min as region_kd_min,
)
from ._extrapolation import (
    ExtrapolationWarning as ExtrapolationWarning,
    extrapolation as extrapolation,
    measured_region as measured_region,
)
from ._figure import plot_envelope as plot_envelope
from ._spec import (
    KD as KD,
    BoundRequirement as BoundRequirement,
    Requirement as Requirement,
    Spec as Spec,
    bind_requirements as bind_requirements,
    load_spec as load_spec,
    parse_spec as parse_spec,
)
from ._unit import (
    UnitAcceptance as UnitAcceptance,
    accept_campaign as accept_campaign,
    accept_json as accept_json,
    bind_to_campaign as bind_to_campaign,
    summary_text as summary_text,
    write_accept as write_accept,
)
