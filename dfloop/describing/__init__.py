"""Describing-function objects: one protocol, analytic static elements, numeric DFs, compositions."""
from . import composition, numeric, static
from .base import DescribingFunction, negative_inverse
from .composition import *  # noqa: F401,F403
from .numeric import *  # noqa: F401,F403
from .static import *  # noqa: F401,F403

__all__ = ["DescribingFunction", "negative_inverse", *static.__all__, *numeric.__all__, *composition.__all__]
