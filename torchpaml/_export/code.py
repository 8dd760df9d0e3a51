r"""The closed form as text a user pastes into their own code: Python, C and LaTeX, printed by sympy.

The Python and the C text hold the rates ``derivative(t, x, u)``, the output ``output(x, u)``, and the step of the
model's method: classical RK4 at ``substeps`` steps per sample interval, the input moving linearly between the two
samples (first-order hold; with ``hold="zoh"`` held at the first),

$$ x_{k+1} = \Phi(t_k, x_k, u_k, u_{k+1}, h_k), $$

the step that :func:`~torchpaml.simulate` takes with ``RK4(substeps=m)``. The Python text adds ``simulate(t, u,
x0)`` and runs with the standard library alone. The LaTeX text is the ODE and the output map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import sympy
import torch
from sympy.printing.c import C99CodePrinter
from sympy.printing.pycode import PythonCodePrinter

from torchpaml._errors import ConfigurationError
from torchpaml._export.closed_form import ClosedForm, closed_form
from torchpaml._export.residual_step import ResidualStep, residual_step
from torchpaml._fit.fitted_model import FittedModel
from torchpaml._grid import check_hold
from torchpaml._simulate.compiled import PRODUCTS
from torchpaml._text import inert_comment

__all__ = ["ExportedStep", "c_code", "c_unpacking", "exported_step", "latex_code", "python_code"]

#: Largest $h\,\rho(A)$ per RK4 substep where a model simulated exactly (linear physics) is exported: RK4's local
#: error is then $(0.05)^5/120 \approx 3\cdot10^{-9}$ of the state per substep.
EXACT_SUBSTEP = 0.05


@dataclass(frozen=True)
class ExportedStep:
    """What an exporter prints: the closed form, the RK4 substeps per sample interval, the input's hold, and the
    residual's one-step map where the model has one (the ONNX export alone prints it)."""

    form: ClosedForm
    substeps: int
    hold: str
    equation: str
    residual: ResidualStep | None = None

    def grey_box(self, what: str) -> ExportedStep:
        """This step, refused in one line where it has a residual: ``what`` (code, an FMU) prints the grey box."""
        if self.residual is not None:
            raise ConfigurationError(f"cannot export the residual of a hybrid (hybrid.pt) as {what}: they print the "
                                     "grey box; export model.pt, or the hybrid's one-step map as ONNX (--onnx)")
        return self


def _substeps(model: FittedModel) -> int:
    """The RK4 substeps of the export (module docstring): the model's own where it steps explicitly; for a model
    simulated exactly, enough for :data:`EXACT_SUBSTEP` at the records' sampling interval."""
    method = model.solver.stepping()
    if method is not None and method.stability is None:
        raise ConfigurationError(f"{model.physics.display_name} is simulated by the implicit {type(method).__name__} (stiff "
                                 "physics), and the exports and the tracker's filter step by explicit RK4, whose "
                                 "numbers would not be the model's; where the physics allows it, fit and save it with "
                                 "an explicit solver (solver=RK4(substeps=N))")
    if method is not None:
        return method.substeps
    base = model.physics.linear_base()
    if base is None or model.step is None:
        raise ConfigurationError(f"cannot export {model.physics.display_name}: its solver ({model.solver!r}) has no "
                                 "fixed step to print; fit it with RK4, or save it from a diagnosis (which records "
                                 "the sampling interval)")
    A = base.state_space()[0].detach()
    rate = float(torch.linalg.matrix_norm(A, ord=2)) if A.numel() else 0.0
    return max(1, math.ceil(model.step * rate / EXACT_SUBSTEP))


def exported_step(model: FittedModel) -> ExportedStep:
    """The closed form of ``model``'s physics and its step (module docstring), with the residual's one-step map
    (:mod:`~torchpaml._export.residual_step`) at the records' sampling interval where the model has one."""
    form = closed_form(model.physics, model.inputs, model.outputs)
    residual = None
    if model.residual is not None:
        if model.step is None:
            raise ConfigurationError("cannot export the residual without the records' sampling interval (its filter is "
                                     "discretised at it): save the hybrid from a diagnosis, or give FittedModel(step=)")
        residual = residual_step(model.residual, form.inputs, model.step)
    # the equation and the hold are printed into comments and docstrings: inert text and a known hold, whatever the
    # model's classes hold
    return ExportedStep(form, _substeps(model), check_hold(model.hold), inert_comment(model.physics.equation()),
                        residual)


def _assignments(printer, names, expressions, indent: str, terminator: str = "") -> list[str]:
    return [f"{indent}{name} = {printer.doprint(expression)}{terminator}" for name, expression in zip(names, expressions)]


def python_code(step: ExportedStep) -> str:
    """The Python text (module docstring)."""
    form, printer = step.grey_box("code").form, PythonCodePrinter({"standard": "python3"})
    x = ", ".join(s.name for s in form.states) + ","
    u = ", ".join(s.name for s in form.inputs) + ","
    rates = _assignments(printer, [f"d_{s.name}" for s in form.states], form.rates, "    ")
    outputs = _assignments(printer, form.outputs, form.output, "    ")
    slope = "(u1[i] - u0[i]) / h" if step.hold == "foh" else "0.0"
    return f'''"""{step.equation}: exported by torchpaml (RK4, {step.substeps} substep(s) per sample, {step.hold} input).

derivative(t, x, u) -> dx/dt; output(x, u) -> y; step(t, x, u0, u1, h) -> the state one sample later;
simulate(t, u, x0) -> the outputs at every sample. x: ({", ".join(s.name for s in form.states)});
u: ({", ".join(s.name for s in form.inputs)}); y: ({", ".join(form.outputs)}).
"""
import math

SUBSTEPS = {step.substeps}


def derivative(t, x, u):
    {x} = x
    {u} = u
{chr(10).join(rates)}
    return [{", ".join(f"d_{s.name}" for s in form.states)}]


def output(x, u):
    {x} = x
    {u} = u
{chr(10).join(outputs)}
    return [{", ".join(form.outputs)}]


def step(t, x, u0, u1, h):
    slope = [{slope} for i in range(len(u0))]
    d = h / SUBSTEPS
    for j in range(SUBSTEPS):
        a = t + j * d
        ua = [u0[i] + slope[i] * (a - t) for i in range(len(u0))]
        um = [u0[i] + slope[i] * (a + d / 2 - t) for i in range(len(u0))]
        uc = [u0[i] + slope[i] * (a + d - t) for i in range(len(u0))]
        k1 = derivative(a, x, ua)
        k2 = derivative(a + d / 2, [x[i] + d / 2 * k1[i] for i in range(len(x))], um)
        k3 = derivative(a + d / 2, [x[i] + d / 2 * k2[i] for i in range(len(x))], um)
        k4 = derivative(a + d, [x[i] + d * k3[i] for i in range(len(x))], uc)
        x = [x[i] + d / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]) for i in range(len(x))]
    return x


def simulate(t, u, x0=None):
    """t: sample times; u: one list of inputs per sample; x0: the initial state (rest by default)."""
    x = list(x0) if x0 is not None else [0.0] * {len(form.states)}
    y = [output(x, u[0])]
    for k in range(len(t) - 1):
        x = step(t[k], x, u[k], u[k + 1], t[k + 1] - t[k])
        y.append(output(x, u[k + 1]))
    return y
'''


def c_unpacking(form: ClosedForm) -> str:
    """C lines naming each state and input of ``form`` from the arrays ``state_`` and ``input_``."""
    return "".join(f"    const double {s.name} = state_[{i}];\n" for i, s in enumerate(form.states)) + \
        "".join(f"    const double {s.name} = input_[{i}];\n" for i, s in enumerate(form.inputs))


def c_code(step: ExportedStep) -> str:
    """The C99 text (module docstring): ``derivative``, ``output`` and ``step`` on double arrays."""
    form, printer = step.grey_box("code").form, C99CodePrinter()
    unpack = c_unpacking(form)
    rates = "".join(f"    rate_[{i}] = {printer.doprint(PRODUCTS(e))};\n" for i, e in enumerate(form.rates))
    outputs = "".join(f"    output_[{i}] = {printer.doprint(PRODUCTS(e))};\n" for i, e in enumerate(form.output))
    n, m = len(form.states), len(form.inputs)
    slope = "(u1[i] - u0[i]) / h" if step.hold == "foh" else "0.0"
    return f"""/* {step.equation}: exported by torchpaml (RK4, {step.substeps} substep(s) per sample, {step.hold} input). */
#include <math.h>

#define N_STATES {n}
#define N_INPUTS {m}
#define N_OUTPUTS {len(form.outputs)}
#define SUBSTEPS {step.substeps}

static void derivative(double {form.time.name}, const double *state_, const double *input_, double *rate_) {{
    (void){form.time.name};
{unpack}{rates}}}

static void output(const double *state_, const double *input_, double *output_) {{
{unpack}{outputs}}}

/* x (N_STATES) advanced from t by h, the input u0 at t and u1 at t + h */
static void step(double t, double *x, const double *u0, const double *u1, double h) {{
    double slope[N_INPUTS], ua[N_INPUTS], um[N_INPUTS], uc[N_INPUTS];
    double k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES], z[N_STATES];
    const double d = h / SUBSTEPS;
    for (int i = 0; i < N_INPUTS; i++) slope[i] = {slope};
    for (int j = 0; j < SUBSTEPS; j++) {{
        const double a = t + j * d;
        for (int i = 0; i < N_INPUTS; i++) {{
            ua[i] = u0[i] + slope[i] * (a - t);
            um[i] = u0[i] + slope[i] * (a + d / 2 - t);
            uc[i] = u0[i] + slope[i] * (a + d - t);
        }}
        derivative(a, x, ua, k1);
        for (int i = 0; i < N_STATES; i++) z[i] = x[i] + d / 2 * k1[i];
        derivative(a + d / 2, z, um, k2);
        for (int i = 0; i < N_STATES; i++) z[i] = x[i] + d / 2 * k2[i];
        derivative(a + d / 2, z, um, k3);
        for (int i = 0; i < N_STATES; i++) z[i] = x[i] + d * k3[i];
        derivative(a + d, z, uc, k4);
        for (int i = 0; i < N_STATES; i++) x[i] += d / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    }}
}}
"""


def latex_code(step: ExportedStep) -> str:
    """The LaTeX text: one line per rate and per output."""
    form = step.grey_box("code").form
    lines = [rf"\dot{{{sympy.latex(s)}}} &= {sympy.latex(e)}" for s, e in zip(form.states, form.rates)]
    lines += [rf"{sympy.latex(sympy.Symbol(name))} &= {sympy.latex(e)}" for name, e in zip(form.outputs, form.output)]
    return "\\begin{aligned}\n" + " \\\\\n".join(lines) + "\n\\end{aligned}\n"
