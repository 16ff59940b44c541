"""Identification, data -> model: DMDModel and its reports, fit_dmd and its ridge routes,
alpha selection (select_alpha, AlphaCurve) and OnlineDMD."""

from .model import (
    AlphaCurve,
    DampingReport,
    DMDModel,
    OnlineDMD,
    StabilityReport,
    fit_dmd,
    select_alpha,
)

__all__ = [
    "DMDModel",
    "StabilityReport",
    "DampingReport",
    "AlphaCurve",
    "OnlineDMD",
    "fit_dmd",
    "select_alpha",
]
