"""A fitted model in the tools engineers use: its closed form as Python, C and LaTeX, an FMU, an ONNX step."""

from torchpaml._export.export import export_model

__all__ = ["export_model"]
