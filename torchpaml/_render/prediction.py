"""A prediction as a CSV file: the record's time and inputs, the model's outputs and states, and the band."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from torchpaml._data import Record
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._model.prediction import Prediction

__all__ = ["write_prediction"]


def write_prediction(model: FittedModel, record: Record, prediction: Prediction, out: str | Path) -> Path:
    """Write ``prediction`` of ``model`` on ``record`` to the CSV ``out``: a first line ``# {json}`` (the model's
    equation, the initial state and its policy, the band's level), then the columns ``t``, the inputs, the outputs
    (the model's channel names, else ``y`` or ``y1, y2, …``), the states (``state_NAME``, by the physics' state
    names) and, with a band, ``OUTPUT_lower`` and ``OUTPUT_upper``. Returns the path."""
    outputs = list(model.outputs) or record.output_names
    columns = {"t": record.t, **{name: record.u[:, i] for i, name in enumerate(record.input_names)},
               **{name: prediction.y[:, i] for i, name in enumerate(outputs)},
               **{f"state_{name}": prediction.states[:, i] for i, name in enumerate(model.physics.state_names)}}
    if prediction.lower is not None:
        for i, name in enumerate(outputs):
            columns[f"{name}_lower"], columns[f"{name}_upper"] = prediction.lower[:, i], prediction.upper[:, i]
    metadata = {"model": model.physics.equation(), "initial_state": model.initial_state.name,
                "x0": prediction.x0.tolist(), "band_level": prediction.level, "inputs": record.input_names,
                "outputs": outputs}
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    table = torch.stack(list(columns.values()), dim=1).numpy()
    with out.open("w") as file:
        file.write(f"# {json.dumps(metadata)}\n{','.join(columns)}\n")
        np.savetxt(file, table, delimiter=",", fmt="%.17g")
    return out
