"""pytest plugin for texture-regression images: the ``texture_regression`` fixture (see ``plugin``).

Comparison functions are usable without pytest: ``from pytest_uvbake.compare import compare_images``.
"""

from .compare import Comparison, compare_images, diff_image

__all__ = ["Comparison", "compare_images", "diff_image"]
