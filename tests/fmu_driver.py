"""An FMU run by FMPy alone, as a Modelica or Python user would: no torchpaml here.

FMPy 0.3.32's ``simulate_fmu(..., set_input_derivatives=True)`` fails for an FMU with fewer than nine inputs (it
sizes the derivatives' buffer at nine), so this driver sets each input and its slope itself
(``fmi2SetRealInputDerivatives``): the first-order hold between samples that the model was fitted with.
"""

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


def run_fmu(path: str, t: np.ndarray, u: np.ndarray, start: dict[str, float] | None = None) -> np.ndarray:
    """The FMU's outputs (time, n_y) at the samples ``t`` (time,) driven by ``u`` (time, n_u), from its parameters'
    start values overridden by ``start``."""
    description = read_model_description(path)
    refs = {v.name: v.valueReference for v in description.modelVariables}
    inputs = [refs[v.name] for v in description.modelVariables if v.causality == "input"]
    outputs = [refs[v.name] for v in description.modelVariables if v.causality == "output"]
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=extract(path),
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName="device")
    fmu.instantiate()
    fmu.setupExperiment(startTime=float(t[0]))
    fmu.enterInitializationMode()
    for name, value in (start or {}).items():
        fmu.setReal([refs[name]], [value])
    fmu.exitInitializationMode()
    y = []
    for k in range(len(t)):
        fmu.setReal(inputs, list(u[k]))
        y.append(fmu.getReal(outputs))
        if k + 1 < len(t):
            h = float(t[k + 1] - t[k])
            fmu.setRealInputDerivatives(inputs, [1] * len(inputs), list((u[k + 1] - u[k]) / h))
            fmu.doStep(float(t[k]), h)
    fmu.terminate()
    fmu.freeInstance()
    return np.array(y)
