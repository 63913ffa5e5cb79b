"""Describing-function objects: one protocol, analytic static elements, numeric DFs, compositions."""
from .base import DescribingFunction, negative_inverse

__all__ = ["DescribingFunction", "negative_inverse"]
