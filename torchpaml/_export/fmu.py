r"""The grey box as an FMU, FMI 2.0: the C text of :func:`~torchpaml._export.code.c_code` compiled, in two kinds.

**Co-simulation** (``write_fmu(..., kind="co-simulation")``, ``--fmu``). ``fmi2DoStep(t, h)`` takes RK4 at the
model's substeps over $h$, the input moving along the derivative the importer sets with
``fmi2SetRealInputDerivatives`` (``canInterpolateInputs``); without one, the input is held over the step. A
co-simulation master that sets each step's slope, $(u_{k+1} - u_k)/h$, gets the first-order hold the model was
fitted with (``tests/fmu_driver.py`` does). FMPy's ``simulate_fmu`` does not: at $t_k$ it passes the slope of the
interval *before* $t_k$, or none, so a model fitted with a first-order hold is off by the input's change over a step
(1.4e-2 relative RMS on the demo's validation record).

**Model exchange** (``kind="model-exchange"``, ``--fmu-me``). The model is a sampled-data system: it has no
continuous state, and at each sample time (a time event every ``sample`` seconds from the start, the model's
sampling interval) its state takes the model's RK4 step from the last sample's input to the one the importer has
just set, $x_{k+1} = \Phi(t_k, x_k, u_k, u_{k+1}, h)$. Any importer that sets the input at the event (FMPy's
``simulate_fmu`` with an input table and ``output_interval`` the sampling interval, the call a user makes) therefore
runs exactly the model's step: it reproduces the model to rounding.

Both carry the records' channel names: one ``input`` per input channel, one ``output`` per output channel, the states
as ``local`` variables ``state_NAME`` and their initial values as parameters ``x0_NAME`` (rest by default: set them
to start elsewhere). The outputs are $h(x, u)$ at the current state and input. The FMU holds
``modelDescription.xml``, the binary for this platform under ``binaries/`` and the source under ``sources/``;
building it needs a C compiler (``cc``) and the FMI 2 headers that FMPy ships (``pip install torchpaml[export]``).
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

__all__ = ["KINDS", "write_fmu"]

#: The C of the FMI 2.0 interface both kinds share, around the model's ``derivative``, ``output`` and ``step``.
COMMON = r"""
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

#define N_VARIABLES (N_INPUTS + N_OUTPUTS + 2 * N_STATES)

typedef struct {
    double time, start, x[N_STATES], x0[N_STATES], u[N_INPUTS], du[N_INPUTS], u_last[N_INPUTS];
    long samples;
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
    if (type != FMU_TYPE || strcmp(guid, GUID) != 0) return NULL;
    Instance *m = (Instance *)calloc(1, sizeof(Instance));
    if (m && callbacks) m->callbacks = *callbacks;
    return m;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol, fmi2Real tolerance, fmi2Real start,
                               fmi2Boolean stop, fmi2Real stopTime) {
    (void)tol; (void)tolerance; (void)stop; (void)stopTime;
    ((Instance *)c)->time = ((Instance *)c)->start = start; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *m = (Instance *)c; memcpy(m->x, m->x0, sizeof m->x); memcpy(m->u_last, m->u, sizeof m->u);
    m->samples = 0; return fmi2OK; }
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
"""

#: The co-simulation interface: ``fmi2DoStep`` takes the RK4 step, the input along the derivative the importer sets.
CO_SIMULATION = r"""
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

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference v[], size_t n,
    const fmi2Integer o[], fmi2Real x[]) UNSUPPORTED()
fmi2Status fmi2CancelStep(fmi2Component c) UNSUPPORTED()
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *s) UNSUPPORTED()
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *x) UNSUPPORTED()
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *x) UNSUPPORTED()
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *x) UNSUPPORTED()
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *x) UNSUPPORTED()
"""

#: The model-exchange interface (module docstring).
MODEL_EXCHANGE = r"""
/* A sampled-data model: no continuous state; at each sample time (a time event every SAMPLE seconds from the start)
   the state takes the model's RK4 step from the last sample's input to this one's, which the importer has set. */
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Instance *)c)->time = t; return fmi2OK; }
fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Instance *m = (Instance *)c;
    const double last = m->start + m->samples * SAMPLE, next = m->start + (m->samples + 1) * SAMPLE;
    if (m->time >= next - 1e-9 * SAMPLE) {
        step(last, m->x, m->u_last, m->u, m->time - last);
        memcpy(m->u_last, m->u, sizeof m->u);
        m->samples++;
    }
    info->newDiscreteStatesNeeded = fmi2False; info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False; info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2True; info->nextEventTime = m->start + (m->samples + 1) * SAMPLE;
    return fmi2OK;
}
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean prior, fmi2Boolean *event, fmi2Boolean *stop) {
    (void)c; (void)prior; *event = fmi2False; *stop = fmi2False; return fmi2OK; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) {
    (void)c; (void)x; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    (void)c; (void)x; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n) { (void)c; (void)dx; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n) { (void)c; (void)z; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
    (void)c; (void)x; return n ? fmi2Error : fmi2OK; }
"""


#: The FMU kinds: each one's interface C, its FMI type constant and its element of ``modelDescription.xml``.
KINDS = ("co-simulation", "model-exchange")


def _element(kind: str, identifier: str) -> str:
    if kind == "co-simulation":
        return (f'  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true"\n'
                '    canInterpolateInputs="true" canBeInstantiatedOnlyOncePerProcess="false"/>')
    return (f'  <ModelExchange modelIdentifier="{identifier}" completedIntegratorStepNotNeeded="true"\n'
            '    canBeInstantiatedOnlyOncePerProcess="false"/>')


def _description(step: ExportedStep, identifier: str, guid: str, kind: str, sample: float | None) -> str:
    form = step.form
    variables, index = [], 0
    changes = "continuous" if kind == "co-simulation" else "discrete"  # a sampled-data model's states change at events

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
        variable(f"state_{symbol.name}", f'causality="local" variability="{changes}" initial="calculated"', "")
    for symbol in form.states:
        variable(f"x0_{symbol.name}", 'causality="parameter" variability="fixed" initial="exact"', 'start="0"')
    m, p = len(form.inputs), len(form.outputs)
    outputs = "".join(f'      <Unknown index="{m + i + 1}"/>\n' for i in range(p))
    experiment = "" if sample is None else f'  <DefaultExperiment startTime="0" stepSize="{sample!r}"/>\n'
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(step.equation)} guid="{guid}"
  generationTool="torchpaml" variableNamingConvention="flat" numberOfEventIndicators="0">
{_element(kind, identifier)}
{experiment}  <ModelVariables>
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


def write_fmu(step: ExportedStep, path: str | Path, kind: str = "co-simulation", sample: float | None = None) -> Path:
    """Write the FMU of ``step`` (module docstring) to ``path``; returns it. ``kind``: ``"co-simulation"`` or
    ``"model-exchange"``, which needs ``sample``, the model's sampling interval (s)."""
    step = step.grey_box("an FMU")
    if kind not in KINDS:
        raise ConfigurationError(f"an FMU is of kind {' or '.join(KINDS)}, got {kind!r}")
    if kind == "model-exchange" and not (sample is not None and sample > 0):
        raise ConfigurationError("a model-exchange FMU steps at the records' sampling interval, and the model has none: "
                                 "save it from a diagnosis (which records it), or give FittedModel(step=)")
    _headers()  # FMPy present, else the one-line refusal
    import fmpy

    platform = fmpy.platform
    if not platform.startswith(("linux", "darwin")):
        raise ConfigurationError(f"writing an FMU compiles it with cc, on Linux and macOS; this is {platform}: "
                                 "export the C text (--code model.c) and compile it with your toolchain")
    path = Path(path)
    identifier = "".join(c if c.isalnum() else "_" for c in path.stem) or "model"
    guid = "{" + str(uuid.uuid4()) + "}"
    exchange = kind == "model-exchange"
    header = f'#define GUID "{guid}"\n#define FMU_TYPE {"fmi2ModelExchange" if exchange else "fmi2CoSimulation"}\n'
    if exchange:
        header += f"#define SAMPLE {float(sample)!r}\n"
    source = header + c_code(step) + COMMON + (MODEL_EXCHANGE if exchange else CO_SIMULATION)
    with tempfile.TemporaryDirectory() as folder:
        library = compile_library(source, Path(folder) / f"{identifier}{fmpy.sharedLibraryExtension}",
                                  "writing an FMU", _headers())
        path.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml", _description(step, identifier, guid, kind,
                                                                  sample if exchange else None))
            archive.write(library, f"binaries/{platform}/{library.name}")
            archive.writestr("sources/model.c", source)
    return path
