"""Bijectivity checks of UV layouts: flips, overlaps (raster candidates, exact predicates), texel share.

The package is callable: ``uvbake.validate(uv, F)`` is ``uvbake.validate.validate(uv, F)``.
"""

import sys
import types
from typing import Any

from uvbake.validate.core import validate
from uvbake.validate.report import BACKGROUND_RGB, FLIPPED_RGB, OVERLAP_RGB, ChartVerdict, ValidationReport

__all__ = ["validate", "ValidationReport", "ChartVerdict", "OVERLAP_RGB", "FLIPPED_RGB", "BACKGROUND_RGB"]


class _CallablePackage(types.ModuleType):
    """``uvbake.validate`` names both this package and its entry point; calling it runs the check."""

    def __call__(self, *args: Any, **kwargs: Any) -> ValidationReport:
        return validate(*args, **kwargs)


sys.modules[__name__].__class__ = _CallablePackage
