"""USD export of built models (usd-core's `pxr` only) and its checks against the MJCF."""

from footforge.usd.checks import (
    TOLERANCES,
    compare_with_model,
    comparison_failures,
    validate_stage,
)
from footforge.usd.context import Unsupported
from footforge.usd.export import Exported, export_model, stage_files, write_stage

__all__ = [
    "TOLERANCES",
    "Exported",
    "Unsupported",
    "compare_with_model",
    "comparison_failures",
    "export_model",
    "stage_files",
    "validate_stage",
    "write_stage",
]
