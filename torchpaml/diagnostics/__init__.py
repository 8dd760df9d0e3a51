"""Diagnostics: how the physics compares with the measurements, and where it fails."""

from torchpaml.diagnostics.compare import Comparison, compare

__all__ = ["Comparison", "compare"]
