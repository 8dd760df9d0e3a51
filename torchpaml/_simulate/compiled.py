r"""RK4 compiled from the physics' closed form: the states of a record, sample after sample, at C speed.

**Why.** The shooting engine (:mod:`~torchpaml._simulate.shooting`) pays eager PyTorch's dispatch on every
sequential step, and Newton needs several sweeps where it starts far from the solution (a hardening oscillator
from its linear base: a whole second on 65 536 samples). Sequential RK4 in C costs about 0.1 µs per step of a
2-state model and needs no Newton at all.

**How.** The physics is run once on sympy twins of its tensors (:func:`~torchpaml._symbolic.trace.symbolic_maps`),
which gives its rates as sympy expressions in the symbols ``t_``, ``x_[i]``, ``u_[j]`` and ``p_[k]``: every element of every parameter and buffer is a symbol, read from the live module at each call, so a
fit's new parameters need no new compile. The expressions are printed as C after common-subexpression
elimination, and RK4 runs sample after sample for each row: the stage times, the inputs of the hold and the step
coefficients of :func:`~torchpaml._simulate.steps.rk4_sweep`, so the two agree to rounding (measured: 5e-15
relative on the hard oscillator). The library is compiled once per machine
(:func:`~torchpaml._symbolic.compiler.cached_library`), and the compiled form is kept per
structure (its modules, their plain attributes, its tensors' names, types and shapes, the values of tensor attributes
that are not parameters), shared by every physics object of that structure: change one, and the next call compiles
again.

**Where it is used.** :func:`~torchpaml._simulate.shooting.simulate_shooting` returns these states where no
derivative is recorded; where one is, the same C with the states' sensitivities
(:mod:`~torchpaml._simulate.compiled_gradient`), or, where that cannot carry them, Newton in the engine started from
these states: they are the solution, so its first sweep converges and gives the sensitivities that gradients need.
Where the physics cannot be compiled, :func:`sequential_states` returns ``None`` and the engine goes on as before: a method other than RK4 (its ``sweep`` is the method), a physics
that the operation table cannot take (:mod:`~torchpaml._symbolic.trace`), a structure run by ``functional_call``
(plain tensors in the parameters' place: the engine's differences), more than :data:`MAX_PARAMETERS` parameter elements (a
neural force: its closed form is no faster than its tensors), no C compiler, fewer than :data:`MIN_STEPS` steps
(tracing and compiling a new structure cost about 0.2 s), states that do not stay finite (the engine then
reports where the simulation blew up), or a ``torch.func`` transform running (``jvp``, ``vmap``).
"""

from __future__ import annotations

import ctypes
import logging
import warnings
from collections import OrderedDict

import numpy as np
import sympy
import torch
from sympy.codegen.rewriting import create_expand_pow_optimization
from sympy.printing.c import C99CodePrinter
from sympy.printing.codeprinter import PrintMethodNotImplementedError
from torch import nn

from torchpaml._errors import CompiledPathWarning, ConfigurationError
from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.method import Method
from torchpaml._symbolic.compiler import UnbuildableError, cached_library, compiler, loaded
from torchpaml._symbolic.hoist import hoisted, slot
from torchpaml._symbolic.trace import symbolic_maps

__all__ = ["MAX_PARAMETERS", "MIN_STEPS", "PRODUCTS", "compiled_form", "sequential_states", "transformed", "warn_once"]

log = logging.getLogger(__name__)

#: Fewest RK4 steps (rows x samples x substeps) for which a physics is compiled: below, the shooting engine
#: finishes before a model is traced and compiled (a model's C form is cached by structure, so a diagnosis compiles
#: each once). At 256 the cascaded tanks' records (768 and 1 024 samples) run in C.
MIN_STEPS = 2**8
#: Most parameter and buffer elements of a physics that is compiled.
MAX_PARAMETERS = 256

_LOOP = r"""
int simulate_rows(int rows, int samples, int substeps, int foh, const double *t, const double *u, const double *x0,
                  const double *given_, double *states) {
    double p_[N_EXTENDED];
    extend(given_, p_);
    double x[N_STATES], z[N_STATES], k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES];
    double ua[N_INPUTS + 1], um[N_INPUTS + 1], uc[N_INPUTS + 1];
    for (int r = 0; r < rows; r++) {
        for (int i = 0; i < N_STATES; i++) x[i] = states[(long)r * samples * N_STATES + i] = x0[r * N_STATES + i];
        for (int n = 0; n + 1 < samples; n++) {
            const double h = t[n + 1] - t[n], d = h / substeps, half = d * 0.5, sixth = d * (1.0 / 6.0);
            const double *u0 = u + ((long)r * samples + n) * N_INPUTS, *u1 = u0 + N_INPUTS;
            for (int j = 0; j < substeps; j++) {
                const double fa = (double)j / substeps, fm = (j + 0.5) / substeps, fc = (double)(j + 1) / substeps;
                for (int i = 0; i < N_INPUTS; i++) {
                    const double change = foh ? u1[i] - u0[i] : 0.0;
                    ua[i] = u0[i] + fa * change; um[i] = u0[i] + fm * change; uc[i] = u0[i] + fc * change;
                }
                rates(t[n] + fa * h, x, ua, p_, k1);
                for (int i = 0; i < N_STATES; i++) z[i] = x[i] + half * k1[i];
                rates(t[n] + fm * h, z, um, p_, k2);
                for (int i = 0; i < N_STATES; i++) z[i] = x[i] + half * k2[i];
                rates(t[n] + fm * h, z, um, p_, k3);
                for (int i = 0; i < N_STATES; i++) z[i] = x[i] + d * k3[i];
                rates(t[n] + fc * h, z, uc, p_, k4);
                for (int i = 0; i < N_STATES; i++) x[i] = x[i] + sixth * ((k1[i] + k4[i]) + 2.0 * (k2[i] + k3[i]));
            }
            for (int i = 0; i < N_STATES; i++) states[((long)r * samples + n + 1) * N_STATES + i] = x[i];
        }
    }
    return 0;
}
"""


class _Compiled:
    """One physics' closed form in the parameter symbols ``p_[k]`` (:attr:`rates`, :attr:`output`), its compiled
    ``simulate_rows``, and where its parameter array is read from (:attr:`targets`: each parameter's or buffer's
    name, its first symbol and its size, in the array's order: ``named_parameters`` then ``named_buffers``)."""

    def __init__(self, physics: Dynamics):
        tensors, self._sources, self.targets, count = {}, [], [], 0
        for name, tensor in (*physics.named_parameters(), *physics.named_buffers()):
            symbols = [sympy.Symbol(f"p_[{count + k}]", real=True) for k in range(tensor.numel())]
            tensors[name] = np.array(symbols, dtype=object).reshape(tuple(tensor.shape))
            self._sources.append(name.rpartition(".")[::2])  # (module path, attribute)
            self.targets.append((name, count, tensor.numel()))
            count += tensor.numel()
        n, m = physics.state_dim, physics.input_dim
        self.symbols = {"t": sympy.Symbol("t_", real=True), "x": [sympy.Symbol(f"x_[{i}]", real=True) for i in range(n)],
                        "u": [sympy.Symbol(f"u_[{j}]", real=True) for j in range(m)],
                        "p": [sympy.Symbol(f"p_[{k}]", real=True) for k in range(count)]}
        values = {"t": np.array([self.symbols["t"]], dtype=object), "x": np.array([self.symbols["x"]], dtype=object),
                  "u": np.array([self.symbols["u"]], dtype=object)}
        rates, output = symbolic_maps(physics, values, tensors)
        self.rates, self.output = list(rates.reshape(-1)), list(output.reshape(-1))
        self.name = physics.display_name
        library = cached_library(_source(self, n, m), "simulate", "the compiled simulation")
        self._run = loaded(library).simulate_rows
        self._run.restype = ctypes.c_int
        self._run.argtypes = [ctypes.c_int] * 4 + [ctypes.c_void_p] * 5
        self.sensitivities = None  # the compiled Jacobian (:mod:`~torchpaml._simulate.compiled_jacobian`), on demand

    def parameters(self, physics: Dynamics) -> np.ndarray:
        """The live values of the parameter array ``p_`` in ``physics`` (any physics of this structure), flattened in
        the compiled order: read at each call, so a replaced tensor is seen."""
        parts = [getattr(physics.get_submodule(owner), attribute) for owner, attribute in self._sources]
        if not parts:
            return np.zeros(1)
        return torch.cat([p.detach().reshape(-1).to(torch.float64) for p in parts]).numpy()

    def __call__(self, physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, substeps: int,
                 hold: str) -> torch.Tensor:
        batch, samples, _ = u.shape
        arrays = [np.ascontiguousarray(a.detach().to(torch.float64).numpy()) for a in (t, u, x0)]
        parameters = self.parameters(physics)
        states = np.empty((batch, samples, x0.shape[-1]))
        self._run(batch, samples, substeps, int(hold == "foh"), *[a.ctypes.data for a in arrays],
                  parameters.ctypes.data, states.ctypes.data)
        return torch.from_numpy(states)


class _Printer(C99CodePrinter):
    """C99, with each lifted subexpression (:mod:`~torchpaml._symbolic.hoist`) read from its element of ``p_``."""

    def _print_Symbol(self, expr: sympy.Symbol) -> str:
        k = slot(expr)
        return super()._print_Symbol(expr) if k is None else f"p_[{k}]"


#: Squares and cubes printed as products (``x*x*x``), as torch's ``pow`` computes them (to the bit, so the compiled
#: form and the engine round alike), where C's ``pow`` is a call to the maths library: every C torchpaml writes (the
#: compiled forms, the tracker's filter, the exported model) prints its expressions through it.
PRODUCTS = create_expand_pow_optimization(3)


def c_function(name: str, arguments: str, assignments: dict[str, sympy.Expr]) -> str:
    """``static void name(arguments)`` that evaluates ``assignments`` ({C lvalue: expression}), common
    subexpressions first, squares and cubes as products (:data:`PRODUCTS`): the one printer of every compiled
    function."""
    printer = _Printer()
    shared, reduced = sympy.cse(list(assignments.values()), symbols=sympy.numbered_symbols("c_"))
    try:
        body = "".join(f"    const double {name} = {printer.doprint(PRODUCTS(value))};\n" for name, value in shared)
        body += "".join(f"    {target} = {printer.doprint(PRODUCTS(value))};\n"
                        for target, value in zip(assignments, reduced, strict=True))
    except PrintMethodNotImplementedError as error:  # a function C has no name for: the engine takes the physics
        raise UnbuildableError(f"{name}: its closed form holds a function C has no name for "
                               f"({str(error).splitlines()[0]})") from None
    unused = "".join(f"(void){a.split('*')[-1].split()[-1]}; " for a in arguments.split(","))
    return f"static void {name}({arguments}) {{\n    {unused}\n{body}}}\n"


#: The arguments of the compiled ``rates``.
RATES_ARGUMENTS = "double t_, const double *x_, const double *u_, const double *p_, double *out_"


def rates_function(rates: list) -> str:
    """The C of ``rates(t_, x_, u_, p_, out_)``: what the compiled RK4 and the compiled Jacobian step with."""
    return c_function("rates", RATES_ARGUMENTS, {f"out_[{i}]": value for i, value in enumerate(rates)})


def extend_function(constants: list, count: int) -> str:
    """The C of ``extend(given_, p_)``: the ``count`` parameters copied from ``given_``, then the subexpressions of
    the parameters alone that :func:`~torchpaml._symbolic.hoist.hoisted` lifted out (in ``given_``), past them; and
    ``N_EXTENDED``, the array's size. Each loop extends its parameters once per call."""
    given = {sympy.Symbol(f"p_[{i}]", real=True): sympy.Symbol(f"given_[{i}]", real=True) for i in range(count)}
    copies = {f"p_[{i}]": symbol for i, symbol in enumerate(given.values())}
    lifted = {f"p_[{count + k}]": value.xreplace(given) for k, value in enumerate(constants)}
    return (f"#define N_EXTENDED {max(count + len(constants), 1)}\n"
            + c_function("extend", "const double *given_, double *p_", {**copies, **lifted}))


def variables(symbols: dict) -> set:
    """The symbols of a closed form that change within a simulation: the time, the states and the inputs."""
    return {symbols["t"], *symbols["x"], *symbols["u"]}


def _source(form: _Compiled, n: int, m: int) -> str:
    """The C of ``extend`` (:func:`extend_function`), ``rates`` (:func:`rates_function`) and the RK4 loop
    :data:`_LOOP`."""
    count = len(form.symbols["p"])
    (rates,), constants = hoisted([form.rates], variables(form.symbols), count)
    return (f"#include <math.h>\n#define N_STATES {n}\n#define N_INPUTS {m}\n" + extend_function(constants, count)
            + rates_function(rates) + _LOOP)


def _attribute_key(value) -> object:
    """A module attribute as part of :func:`_signature`: a plain value by its ``repr``; anything else (a function the
    physics calls, an object) by itself, which the key then holds, so that no other object can take its identity
    while the form is kept; an unhashable container by its ``repr``."""
    if isinstance(value, (bool, int, float, str, tuple, type(None))):
        return repr(value)
    try:
        hash(value)
    except TypeError:
        return repr(value)
    return value


def _signature(physics: Dynamics) -> tuple:
    """What a compiled form depends on besides the parameters' values: each module's class and attributes (plain
    values by value, a function or another object by identity: :func:`_attribute_key`), its tensors' names, types
    and shapes, and the values of its tensor attributes that are neither parameters nor buffers
    (the closed form holds those as numbers: a changed one needs a new compile). ``functional_call`` puts plain
    tensors in the parameters' place: that structure is another signature, left to the engine
    (:func:`_reparametrized`), and the module's own is still compiled."""
    return tuple((name, type(module).__module__, type(module).__qualname__,
                  tuple(sorted(((k, _attribute_key(v)) for k, v in vars(module).items()
                                if not k.startswith("_") and k != "training" and not isinstance(v, torch.Tensor)),
                               key=lambda item: item[0])),
                  tuple((k, type(v).__name__, tuple(v.shape))
                        for k, v in (*module._parameters.items(), *module._buffers.items()) if v is not None),
                  tuple((k, tuple(v.shape), v.detach().cpu().to(torch.float64).numpy().tobytes())
                        for k, v in sorted(vars(module).items(), key=lambda item: item[0])
                        if isinstance(v, torch.Tensor) and not isinstance(v, nn.Parameter)))
                 for name, module in physics.named_modules())


#: The compiled forms by structure (:func:`_signature`), shared by every physics object of that structure (a ranking's
#: probes copy a model per strength): the most recent :data:`KEPT_FORMS`.
_FORMS: OrderedDict = OrderedDict()
KEPT_FORMS = 512


def _reparametrized(physics: Dynamics) -> bool:
    """Whether ``functional_call`` runs ``physics`` (a plain tensor in a parameter's place): the central differences
    of a Jacobian the engine computes (:func:`~torchpaml._simulate.sensitivity.difference_jacobian`), which stay on
    the engine's arithmetic."""
    return any(v is not None and not isinstance(v, nn.Parameter)
               for module in physics.modules() for v in module._parameters.values())


def _compiled(physics: Dynamics) -> _Compiled | None:
    """The compiled form of ``physics`` (made once per structure), ``None`` where it cannot be compiled: a physics the
    tracer or the operation table cannot take, or too many parameters, is logged once per structure (the engine is
    its path); a machine that cannot compile or load C warns once (:class:`~torchpaml.CompiledPathWarning`)."""
    signature = _signature(physics)
    if signature in _FORMS:
        _FORMS.move_to_end(signature)
        return _FORMS[signature]
    form = None
    if compiler() is None:
        warn_once("no C compiler (cc, gcc) is on PATH; install one")
    elif _reparametrized(physics):
        log.info("%s is simulated by the torch engine: run by functional_call", physics.display_name)
    elif sum(p.numel() for p in physics.parameters()) > MAX_PARAMETERS:
        log.info("%s is simulated by the torch engine: more than %d parameter elements", physics.display_name,
                 MAX_PARAMETERS)
    else:
        try:
            form = _Compiled(physics)
        except UnbuildableError as error:
            warn_once(str(error))
        except ConfigurationError as error:  # not traceable, an operation the table lacks: the engine simulates it
            log.info("%s is simulated by the torch engine: %s", physics.display_name, error)
        except AttributeError as error:  # a user's model with only what the engine needs of the protocol
            log.info("%s is simulated by the torch engine: %s", type(physics).__name__, error)
    _FORMS[signature] = form
    if len(_FORMS) > KEPT_FORMS:
        _FORMS.popitem(last=False)
    return form


_WARNED: set[str] = set()


def warn_once(reason: str) -> None:
    """One :class:`~torchpaml.CompiledPathWarning` per reason and process."""
    if reason not in _WARNED:
        _WARNED.add(reason)
        warnings.warn(f"the compiled simulation is not available ({reason}); the torch engine simulates instead, "
                      "slower, with the same results", CompiledPathWarning, stacklevel=3)


def transformed() -> bool:
    """Whether a ``torch.func`` transform (``jvp``, ``vmap``, ``grad``) is running: its tensors cannot leave torch."""
    return torch._C._functorch.peek_interpreter_stack() is not None


def compiled_form(physics: Dynamics, solver: Method, steps: int | None = None) -> _Compiled | None:
    """The compiled form of ``physics`` for ``solver``; ``None`` where the module docstring's conditions leave it to
    the shooting engine, among them ``steps`` (rows x samples x substeps, where given) below :data:`MIN_STEPS`: the
    path depends on the record alone, never on what this process compiled before."""
    if not solver.compiles or transformed():
        return None
    if solver.compiles != "rk4":  # the forward library is RK4's; TR-BDF2 runs in the sensitivities' one
        steps = None
    if steps is not None and steps < MIN_STEPS:
        return None
    return _compiled(physics)


def sequential_states(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, solver: Method,
                      hold: str) -> torch.Tensor | None:
    """The states (batch, time, n_state) of ``physics`` from ``x0`` (batch, n_state) driven by ``u`` (batch, time,
    n_input) on ``t`` (time,) by RK4 at ``solver.substeps`` in C, detached; ``None`` where the module docstring's
    conditions leave it to the shooting engine."""
    if solver.compiles != "rk4":
        return None
    form = compiled_form(physics, solver, u.shape[0] * (len(t) - 1) * solver.substeps)
    if form is None:
        return None
    states = form(physics, t, u, x0, solver.substeps, hold).to(x0.dtype)
    return states if bool(torch.isfinite(states).all()) else None
