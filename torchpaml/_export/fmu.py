r"""The grey box as an FMU: FMI 2.0 co-simulation, the C text of :func:`~torchpaml._export.code.c_code` compiled.

The FMU's variables carry the records' channel names: one ``input`` per input channel, one ``output`` per output
channel, the states as ``local`` variables ``state_NAME`` and their initial values as parameters ``x0_NAME`` (rest by default: set
them to start elsewhere). ``fmi2DoStep(t, h)`` takes RK4 at the model's substeps over $h$, the input moving along
the derivative the importer sets with ``fmi2SetRealInputDerivatives`` (``canInterpolateInputs``: FMPy's
``set_input_derivatives=True`` gives the first-order hold the model was fitted with; without it, the input is held).
The outputs are $h(x, u)$ at the current state and input. The FMU holds ``modelDescription.xml``, the binary for
this platform under ``binaries/`` and the source under ``sources/``; building it needs a C compiler (``cc``) and
the FMI 2 headers that FMPy ships (``pip install torchpaml[export]``).
"""

from __future__ import annotations

import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

from torchpaml._errors import ConfigurationError
from torchpaml._export.code import ExportedStep, c_code
from torchpaml._symbolic.compiler import compile_library

__all__ = ["write_fmu"]

#: The C of the FMI 2.0 co-simulation interface around the model's ``derivative``, ``output`` and ``step``.
INTERFACE = r"""
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

#define N_VARIABLES (N_INPUTS + N_OUTPUTS + 2 * N_STATES)

typedef struct {
    double time, x[N_STATES], x0[N_STATES], u[N_INPUTS], du[N_INPUTS];
    fmi2CallbackFunctions callbacks;
} Instance;

static void outputs(const Instance *m, double *y) { output(m->x, m->u, y); }

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean l, size_t n, const fmi2String cat[]) {
    (void)c; (void)l; (void)n; (void)cat; return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *callbacks, fmi2Boolean visible, fmi2Boolean logging) {
    (void)name; (void)location; (void)visible; (void)logging;
    if (type != fmi2CoSimulation || strcmp(guid, GUID) != 0) return NULL;
    Instance *m = (Instance *)calloc(1, sizeof(Instance));
    if (m && callbacks) m->callbacks = *callbacks;
    return m;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol, fmi2Real tolerance, fmi2Real start,
                               fmi2Boolean stop, fmi2Real stopTime) {
    (void)tol; (void)tolerance; (void)stop; (void)stopTime; ((Instance *)c)->time = start; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *m = (Instance *)c; memcpy(m->x, m->x0, sizeof m->x); return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    Instance *m = (Instance *)c; double x0[N_STATES]; memcpy(x0, m->x0, sizeof x0);
    fmi2CallbackFunctions cb = m->callbacks; memset(m, 0, sizeof *m); m->callbacks = cb;
    memcpy(m->x0, x0, sizeof x0); return fmi2OK; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Instance *m = (Instance *)c; double y[N_OUTPUTS]; outputs(m, y);
    for (size_t i = 0; i < n; i++) {
        unsigned r = vr[i];
        if (r < N_INPUTS) value[i] = m->u[r];
        else if (r < N_INPUTS + N_OUTPUTS) value[i] = y[r - N_INPUTS];
        else if (r < N_INPUTS + N_OUTPUTS + N_STATES) value[i] = m->x[r - N_INPUTS - N_OUTPUTS];
        else if (r < N_VARIABLES) value[i] = m->x0[r - N_INPUTS - N_OUTPUTS - N_STATES];
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Instance *m = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        unsigned r = vr[i];
        if (r < N_INPUTS) { m->u[r] = value[i]; m->du[r] = 0.0; }
        else if (r >= N_INPUTS + N_OUTPUTS + N_STATES && r < N_VARIABLES)
            m->x0[r - N_INPUTS - N_OUTPUTS - N_STATES] = value[i];
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Instance *m = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= N_INPUTS || order[i] != 1) return fmi2Error;
        m->du[vr[i]] = value[i];
    }
    return fmi2OK;
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean discard) {
    Instance *m = (Instance *)c; double u1[N_INPUTS]; (void)discard;
    for (int i = 0; i < N_INPUTS; i++) u1[i] = m->u[i] + m->du[i] * h;
    step(t, m->x, m->u, u1, h);
    for (int i = 0; i < N_INPUTS; i++) m->u[i] = u1[i];
    m->time = t + h;
    return fmi2OK;
}

#define UNSUPPORTED(...) { return fmi2Error; }
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference v[], size_t n, fmi2Integer x[]) UNSUPPORTED()
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference v[], size_t n, fmi2Boolean x[]) UNSUPPORTED()
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference v[], size_t n, fmi2String x[]) UNSUPPORTED()
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference v[], size_t n, const fmi2Integer x[]) UNSUPPORTED()
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference v[], size_t n, const fmi2Boolean x[]) UNSUPPORTED()
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference v[], size_t n, const fmi2String x[]) UNSUPPORTED()
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) UNSUPPORTED()
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) UNSUPPORTED()
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) UNSUPPORTED()
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) UNSUPPORTED()
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) UNSUPPORTED()
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) UNSUPPORTED()
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
    const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real df[]) UNSUPPORTED()
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference v[], size_t n,
    const fmi2Integer o[], fmi2Real x[]) UNSUPPORTED()
fmi2Status fmi2CancelStep(fmi2Component c) UNSUPPORTED()
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *s) UNSUPPORTED()
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *x) UNSUPPORTED()
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *x) UNSUPPORTED()
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *x) UNSUPPORTED()
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *x) UNSUPPORTED()
"""


def _description(step: ExportedStep, identifier: str, guid: str) -> str:
    form = step.form
    variables, index = [], 0

    def variable(name: str, attributes: str, real: str) -> None:
        nonlocal index
        variables.append(f'    <ScalarVariable name={quoteattr(name)} valueReference="{index}" {attributes}>'
                         f"<Real {real}/></ScalarVariable>")
        index += 1

    for symbol in form.inputs:
        variable(symbol.name, 'causality="input" variability="continuous"', 'start="0"')
    for name in form.outputs:
        variable(name, 'causality="output" variability="continuous" initial="calculated"', "")
    for symbol in form.states:
        variable(f"state_{symbol.name}", 'causality="local" variability="continuous" initial="calculated"', "")
    for symbol in form.states:
        variable(f"x0_{symbol.name}", 'causality="parameter" variability="fixed" initial="exact"', 'start="0"')
    m, p = len(form.inputs), len(form.outputs)
    outputs = "".join(f'      <Unknown index="{m + i + 1}"/>\n' for i in range(p))
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(step.equation)} guid="{guid}"
  generationTool="torchpaml" variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true"
    canInterpolateInputs="true" canBeInstantiatedOnlyOncePerProcess="false"/>
  <ModelVariables>
{chr(10).join(variables)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{outputs}    </Outputs>
    <InitialUnknowns>
{outputs}    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def _headers() -> Path:
    try:
        import fmpy
    except ImportError:
        raise ConfigurationError("writing an FMU needs the FMI headers that FMPy ships: pip install torchpaml[export] "
                                 "(or pip install fmpy)") from None
    return Path(fmpy.__file__).parent / "c-code"


def write_fmu(step: ExportedStep, path: str | Path) -> Path:
    """Write the FMU of ``step`` (module docstring) to ``path``; returns it."""
    step = step.grey_box("an FMU")
    _headers()  # FMPy present, else the one-line refusal
    import fmpy

    platform = fmpy.platform
    if not platform.startswith(("linux", "darwin")):
        raise ConfigurationError(f"writing an FMU compiles it with cc, on Linux and macOS; this is {platform}: "
                                 "export the C text (--code model.c) and compile it with your toolchain")
    path = Path(path)
    identifier = "".join(c if c.isalnum() else "_" for c in path.stem) or "model"
    guid = "{" + str(uuid.uuid4()) + "}"
    source = f'#define GUID "{guid}"\n' + c_code(step) + INTERFACE
    with tempfile.TemporaryDirectory() as folder:
        library = compile_library(source, Path(folder) / f"{identifier}{fmpy.sharedLibraryExtension}",
                                  "writing an FMU", _headers())
        path.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml", _description(step, identifier, guid))
            archive.write(library, f"binaries/{platform}/{library.name}")
            archive.writestr("sources/model.c", source)
    return path
