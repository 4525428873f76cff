"""From a fitted model to the numbers and files a user reads: derived metrics, fit.json."""

from ._derived import DerivedMetrics as DerivedMetrics, MetricSpec as MetricSpec, derived_metrics_for as derived_metrics_for
from ._pipeline import (
    CampaignFit as CampaignFit,
    campaign_model as campaign_model,
    FitOptions as FitOptions,
    finish_fit as finish_fit,
    fit_campaign as fit_campaign,
    fit_json as fit_json,
    metrics_against_data as metrics_against_data,
    prepare_fit as prepare_fit,
    sampler_kwargs as sampler_kwargs,
    smc_checkpoint_path as smc_checkpoint_path,
    summarise as summarise,
    summary_table as summary_table,
    write_fit as write_fit,
)
