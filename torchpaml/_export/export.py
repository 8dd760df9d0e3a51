"""One call that writes a fitted model's exports: an FMU, an ONNX one-step map, and the closed form as code."""

from __future__ import annotations

from pathlib import Path

from torchpaml._errors import ConfigurationError
from torchpaml._export.code import c_code, exported_step, latex_code, python_code
from torchpaml._export.fmu import write_fmu
from torchpaml._export.onnx_step import write_onnx
from torchpaml._fit.fitted_model import FittedModel

__all__ = ["LANGUAGES", "export_model"]

#: The code a file's suffix asks for.
LANGUAGES = {".py": python_code, ".c": c_code, ".h": c_code, ".tex": latex_code}


def export_model(model: FittedModel, *, fmu: str | Path | None = None, onnx: str | Path | None = None,
                 code: str | Path | None = None, fmu_me: str | Path | None = None) -> list[Path]:
    """Write the exports of ``model`` that are asked for; returns their paths.

    Args:
        model: a fitted model (``torchpaml.load_model(path)``, ``diagnosis.model``, ``estimate.model``).
        fmu: an FMI 2.0 co-simulation FMU of the grey box (:mod:`~torchpaml._export.fmu`).
        fmu_me: an FMI 2.0 model-exchange FMU of the grey box, a sampled-data model at the records' sampling interval:
            what FMPy's ``simulate_fmu`` with an input table runs as the model runs (:mod:`~torchpaml._export.fmu`).
        onnx: the one-step map as ONNX (:mod:`~torchpaml._export.onnx_step`).
        code: the closed form and its step as text (:mod:`~torchpaml._export.code`), the language by the suffix:
            ``.py`` Python, ``.c``/``.h`` C, ``.tex`` LaTeX.

    Raises :class:`~torchpaml.ConfigurationError` in one line naming the part that cannot be exported: an operation
    the exporter does not know (before anything is written), a residual, an implicit solver, a missing C compiler
    or FMI headers for the FMU.
    """
    if fmu is None and onnx is None and code is None and fmu_me is None:
        raise ConfigurationError("nothing to export: name at least one of fmu=, fmu_me=, onnx=, code= (--fmu, "
                                 "--fmu-me, --onnx, --code)")
    printer = None if code is None else LANGUAGES.get(Path(code).suffix)
    if code is not None and printer is None:
        raise ConfigurationError(f"the code file {code} names no language I print; use .py (Python), .c or .h (C), or "
                                 ".tex (LaTeX)")
    step = exported_step(model)
    written = []
    if code is not None:
        Path(code).parent.mkdir(parents=True, exist_ok=True)
        Path(code).write_text(printer(step))
        written.append(Path(code))
    if onnx is not None:
        written.append(write_onnx(step, onnx))
    if fmu is not None:
        written.append(write_fmu(step, fmu))
    if fmu_me is not None:
        written.append(write_fmu(step, fmu_me, "model-exchange", model.step))
    return written
