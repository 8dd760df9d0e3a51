r"""The output and its exact Jacobian in C: RK4's forward sensitivities through the same stages as the compiled RK4.

**What.** For the states $x_k$ of RK4 at ``substeps`` steps per sample (the stages and hold of
:mod:`~torchpaml._simulate.compiled`, the same C for the states, so they are the compiled simulation's to the bit),
each column $j$ carries the state's sensitivity $S_j = \partial x/\partial\theta_j$ through every stage:

$$ K_{s,j} = f_x(z_s)\,Z_{s,j} + f_{\theta_j}(z_s), \qquad Z_{1} = S,\ Z_{2} = S + \tfrac d2 K_1,\
   Z_{3} = S + \tfrac d2 K_2,\ Z_{4} = S + d\,K_3, \qquad
   S \leftarrow S + \tfrac d6\big((K_1 + K_4) + 2(K_2 + K_3)\big), $$

the derivative of the discrete RK4 map itself (the variational equations through the same stages), so the Jacobian
is the exact derivative of the simulated output, not an approximation of it. At each sample
$\partial y/\partial\theta_j = h_x S_j + h_{\theta_j}$. A parameter column starts at $S_j = 0$; an initial-state
column $i$ at $S = e_i$ and has no $f_\theta$ term. $f_x$, $f_\theta$, $h_x$ and $h_\theta$ are sympy's derivatives
of the closed form in the raw parameters' symbols (the constraint maps are in the traced graph), printed as C with
common subexpressions shared. A sign's derivative is 0 and a kink's (``Abs``, ``Max``) is the side's slope, as in
torch.

**Cost.** One pass gives the outputs and all $p + n$ columns: per stage, one evaluation of $f$ and of its
derivatives and $n^2$ multiply-adds per column.

**Where it is used.** :meth:`~torchpaml.FixedStep.jacobian` of RK4 and TR-BDF2 (every fit's and probe's Jacobian
at any record length), where the physics compiles (:func:`~torchpaml._simulate.compiled.compiled_form`) and each
parameter named is one scalar; otherwise ``None``, and the shooting engine's central differences are the Jacobian.
A physics with a kink takes central differences of whole simulations in C instead (:class:`_Sensitivities`,
:func:`_differenced`). TR-BDF2's states (:func:`implicit_states`) are compiled for every physics that compiles.
"""

from __future__ import annotations

import ctypes
import functools
import logging
from collections.abc import Callable

import numpy as np
import sympy
import torch

from torchpaml._errors import SimulationError
from torchpaml._simulate.blowup import blown_up, checked_output
from torchpaml._simulate.compiled import (RATES_ARGUMENTS, _Compiled, c_function, compiled_form, extend_function,
                                          rates_function, sequential_states, variables, warn_once)
from torchpaml._simulate.differences import difference_step
from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.method import Method
from torchpaml._simulate.steps import BDF_NEW, BDF_OLD, D, GAMMA, HALVINGS, MAX_ITERATIONS, NEWTON_TOL, STALL_TOL
from torchpaml._symbolic.compiler import UnbuildableError, cached_library, loaded
from torchpaml._symbolic.hoist import hoisted

__all__ = ["compiled_jacobian", "compiled_sensitivities", "compiled_states", "implicit_states"]

log = logging.getLogger(__name__)

_LOOP = r"""
/* The chain rule for `rows` functions of the states and the parameters: out[r, j] = dp[r, column[j]] (0 for an
   initial state's column) + sum_l dx[r, l] Z[j, l], written at out[r * row_step + j * column_step]. */
static void chain(int rows, const double *dx, const double *dp, int columns, const int *column, const double *Z,
                  double *out, int row_step, int column_step) {
    for (int r = 0; r < rows; r++)
        for (int j = 0; j < columns; j++) {
            double s = column[j] >= 0 ? dp[r * N_PARAMS + column[j]] : 0.0;
            for (int l = 0; l < N_STATES; l++) s += dx[r * N_STATES + l] * Z[j * N_STATES + l];
            out[r * row_step + j * column_step] = s;
        }
}

static void stage(double t_, const double *z, const double *uz, const double *p_, int columns, const int *column,
                  const double *Z, double *K, double *fx, double *fp) {
    derivatives(t_, z, uz, p_, fx, fp);
    chain(N_STATES, fx, fp, columns, column, Z, K, 1, N_STATES);
}

/* What is asked at sample `at` (an array that is NULL is not asked): the outputs and their Jacobian, the states, and
   the states' sensitivities S (columns x N_STATES). */
static void emit(long at, const double *x, const double *un, const double *p_, int columns, const int *column,
                 const double *S, double *y, double *J, double *states, double *sens, double *hx, double *hp) {
    if (y != NULL) {
        double *yn = y + at * N_OUTPUTS, *Jn = J + at * N_OUTPUTS * columns;
        outputs(x, un, p_, yn, hx, hp);
        chain(N_OUTPUTS, hx, hp, columns, column, S, Jn, columns, 1);
    }
    if (states != NULL)
        for (int i = 0; i < N_STATES; i++) states[at * N_STATES + i] = x[i];
    if (sens != NULL)
        for (int i = 0; i < columns * N_STATES; i++) sens[at * columns * N_STATES + i] = S[i];
}

typedef struct {
    double *S, *Z, *K1, *K2, *K3, *K4, *fx, *fp, *hx, *hp, *M, *A;
} Work;

static double *work(Work *w, int columns) {
    const size_t v = (size_t)columns * N_STATES;
    double *all = calloc(7 * v + N_STATES * (2 * N_STATES + N_PARAMS) + N_OUTPUTS * (N_STATES + N_PARAMS) + 1,
                         sizeof(double));
    if (all == NULL) return NULL;
    w->S = all; w->Z = w->S + v; w->K1 = w->Z + v; w->K2 = w->K1 + v; w->K3 = w->K2 + v; w->K4 = w->K3 + v;
    w->A = w->K4 + v; w->fx = w->A + v; w->M = w->fx + N_STATES * N_STATES; w->fp = w->M + N_STATES * N_STATES;
    w->hx = w->fp + N_STATES * N_PARAMS; w->hp = w->hx + N_OUTPUTS * N_STATES;
    return all;
}

static void start_row(const double *x0, int columns, const int *column, double *x, double *S) {
    for (int i = 0; i < N_STATES; i++) x[i] = x0[i];
    for (int j = 0; j < columns; j++)
        for (int i = 0; i < N_STATES; i++) S[j * N_STATES + i] = column[j] == -1 - i ? 1.0 : 0.0;
}

static void stage_inputs(const double *u0, const double *u1, int foh, double fa, double fm, double fc, double *ua,
                         double *um, double *uc) {
    for (int i = 0; i < N_INPUTS; i++) {
        const double change = foh ? u1[i] - u0[i] : 0.0;
        ua[i] = u0[i] + fa * change; um[i] = u0[i] + fm * change; uc[i] = u0[i] + fc * change;
    }
}

int rk4_rows(int rows, int samples, int substeps, int foh, int columns, const int *column, const double *t,
             const double *u, const double *x0, const double *given_, double *states, double *y,
             double *J, double *sens) {
    double p_[N_EXTENDED];
    extend(given_, p_);
    Work w;
    double *all = work(&w, columns);
    if (all == NULL) return -1;
    const int v = columns * N_STATES;
    double *S = w.S, *Z = w.Z, *K1 = w.K1, *K2 = w.K2, *K3 = w.K3, *K4 = w.K4;
    double x[N_STATES], z[N_STATES], k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES];
    double ua[N_INPUTS + 1], um[N_INPUTS + 1], uc[N_INPUTS + 1];
    for (int r = 0; r < rows; r++) {
        const long first = (long)r * samples;
        start_row(x0 + r * N_STATES, columns, column, x, S);
        emit(first, x, u + first * N_INPUTS, p_, columns, column, S, y, J, states, sens, w.hx, w.hp);
        for (int n = 0; n + 1 < samples; n++) {
            const double h = t[n + 1] - t[n], d = h / substeps, half = d * 0.5, sixth = d * (1.0 / 6.0);
            const double *u0 = u + (first + n) * N_INPUTS, *u1 = u0 + N_INPUTS;
            for (int j = 0; j < substeps; j++) {
                const double fa = (double)j / substeps, fm = (j + 0.5) / substeps, fc = (double)(j + 1) / substeps;
                stage_inputs(u0, u1, foh, fa, fm, fc, ua, um, uc);
                rates(t[n] + fa * h, x, ua, p_, k1);
                stage(t[n] + fa * h, x, ua, p_, columns, column, S, K1, w.fx, w.fp);
                for (int i = 0; i < N_STATES; i++) z[i] = x[i] + half * k1[i];
                for (int i = 0; i < v; i++) Z[i] = S[i] + half * K1[i];
                rates(t[n] + fm * h, z, um, p_, k2);
                stage(t[n] + fm * h, z, um, p_, columns, column, Z, K2, w.fx, w.fp);
                for (int i = 0; i < N_STATES; i++) z[i] = x[i] + half * k2[i];
                for (int i = 0; i < v; i++) Z[i] = S[i] + half * K2[i];
                rates(t[n] + fm * h, z, um, p_, k3);
                stage(t[n] + fm * h, z, um, p_, columns, column, Z, K3, w.fx, w.fp);
                for (int i = 0; i < N_STATES; i++) z[i] = x[i] + d * k3[i];
                for (int i = 0; i < v; i++) Z[i] = S[i] + d * K3[i];
                rates(t[n] + fc * h, z, uc, p_, k4);
                stage(t[n] + fc * h, z, uc, p_, columns, column, Z, K4, w.fx, w.fp);
                for (int i = 0; i < N_STATES; i++) x[i] = x[i] + sixth * ((k1[i] + k4[i]) + 2.0 * (k2[i] + k3[i]));
                for (int i = 0; i < v; i++) S[i] = S[i] + sixth * ((K1[i] + K4[i]) + 2.0 * (K2[i] + K3[i]));
            }
            const long at = first + n + 1;
            emit(at, x, u1, p_, columns, column, S, y, J, states, sens, w.hx, w.hp);
        }
    }
    free(all);
    return 0;
}

/* LU with partial pivoting of M (n x n, in place), pivots in p; 0 where M is singular. */
static int factor(double *M, int *p) {
    for (int k = 0; k < N_STATES; k++) {
        int best = k;
        for (int i = k + 1; i < N_STATES; i++) if (fabs(M[i * N_STATES + k]) > fabs(M[best * N_STATES + k])) best = i;
        p[k] = best;
        if (M[best * N_STATES + k] == 0.0) return 0;
        if (best != k)
            for (int l = 0; l < N_STATES; l++) {
                const double s = M[k * N_STATES + l]; M[k * N_STATES + l] = M[best * N_STATES + l];
                M[best * N_STATES + l] = s;
            }
        for (int i = k + 1; i < N_STATES; i++) {
            M[i * N_STATES + k] /= M[k * N_STATES + k];
            for (int l = k + 1; l < N_STATES; l++) M[i * N_STATES + l] -= M[i * N_STATES + k] * M[k * N_STATES + l];
        }
    }
    return 1;
}

static void solve(const double *M, const int *p, double *b) {
    for (int k = 0; k < N_STATES; k++) {
        const double s = b[k]; b[k] = b[p[k]]; b[p[k]] = s;
        for (int i = k + 1; i < N_STATES; i++) b[i] -= M[i * N_STATES + k] * b[k];
    }
    for (int k = N_STATES - 1; k >= 0; k--) {
        for (int l = k + 1; l < N_STATES; l++) b[k] -= M[k * N_STATES + l] * b[l];
        b[k] /= M[k * N_STATES + k];
    }
}

static double finite_or_zero(double v) { return isfinite(v) ? v : 0.0; }

/* M = I - dh * f_x(z), its non-finite slopes left out (an infinite slope of a square root at zero), factored. */
static int implicit_matrix(double tz, const double *z, const double *uz, const double *p_, double dh, double *M,
                           int *pivot) {
    state_jacobian(tz, z, uz, p_, M);
    for (int i = 0; i < N_STATES * N_STATES; i++) M[i] = (i % (N_STATES + 1) == 0 ? 1.0 : 0.0) - dh * finite_or_zero(M[i]);
    return factor(M, pivot);
}

/* max_i |g_i| / scale_i: 0 where it is not finite (a blown-up row is the caller's to find). */
static double size_of(const double *g, const double *scale) {
    double s = 0.0;
    int nan = 0;
    for (int i = 0; i < N_STATES; i++) {
        const double v = fabs(g[i]) / scale[i];
        if (v != v) nan = 1; else if (v > s) s = v;
    }
    return nan || isinf(s) ? 0.0 : s;
}

/* z = a + dh f(tz, z, uz) by Newton from z, as the engine's TR-BDF2 stage: each step halved until it lowers the
   residual, stopped where the update is below NEWTON_TOL of the scale. 0 when solved. */
static int newton(double tz, const double *uz, const double *p_, const double *a, double dh, double *z,
                  const double *scale, double *M) {
    double f[N_STATES], g[N_STATES], update[N_STATES], trial[N_STATES], tf[N_STATES], tg[N_STATES], change = 0.0;
    int pivot[N_STATES];
    for (int iteration = 0; iteration < MAX_ITERATIONS; iteration++) {
        rates(tz, z, uz, p_, f);
        for (int i = 0; i < N_STATES; i++) g[i] = z[i] - a[i] - dh * f[i];
        const double size = size_of(g, scale);
        if (!implicit_matrix(tz, z, uz, p_, dh, M, pivot)) return 2;
        for (int i = 0; i < N_STATES; i++) update[i] = g[i];
        solve(M, pivot, update);
        double step = 1.0;
        for (int halving = 0; halving < HALVINGS; halving++) {
            for (int i = 0; i < N_STATES; i++) trial[i] = z[i] - step * update[i];
            rates(tz, trial, uz, p_, tf);
            for (int i = 0; i < N_STATES; i++) tg[i] = trial[i] - a[i] - dh * tf[i];
            const double trial_size = size_of(tg, scale);
            if (!(trial_size > size * (1 - 1e-4 * step) && trial_size > NEWTON_TOL)) break;
            step = step / 2;
        }
        change = 0.0;
        for (int i = 0; i < N_STATES; i++) {
            z[i] = trial[i];
            const double moved = finite_or_zero(fabs(step * update[i]) / scale[i]);
            if (moved > change) change = moved;
        }
        if (change <= NEWTON_TOL) return 0;
    }
    return change > STALL_TOL;
}

/* The sensitivities of a solved stage: Z = M^{-1} (A + dh f_theta(z)), M = I - dh f_x(z) at the solution. */
static int implicit_sensitivities(double tz, const double *z, const double *uz, const double *p_, double dh,
                                  int columns, const int *column, const double *A, double *Z, Work *w) {
    int pivot[N_STATES];
    if (columns == 0) return 0;
    derivatives(tz, z, uz, p_, w->fx, w->fp);
    if (!implicit_matrix(tz, z, uz, p_, dh, w->M, pivot)) return 2;
    for (int j = 0; j < columns; j++) {
        double *b = Z + j * N_STATES;
        for (int i = 0; i < N_STATES; i++)
            b[i] = A[j * N_STATES + i] + (column[j] >= 0 ? dh * w->fp[i * N_PARAMS + column[j]] : 0.0);
        solve(w->M, pivot, b);
    }
    return 0;
}

int trbdf2_rows(int rows, int samples, int substeps, int foh, int columns, const int *column, const double *t,
                const double *u, const double *x0, const double *given_, double *states, double *y,
                double *J, double *sens) {
    double p_[N_EXTENDED];
    extend(given_, p_);
    Work w;
    double *all = work(&w, columns);
    if (all == NULL) return -1;
    const int v = columns * N_STATES;
    double *S = w.S, *Z = w.Z, *A = w.A;
    double x[N_STATES], a[N_STATES], middle[N_STATES], f[N_STATES], scale[N_STATES];
    double ua[N_INPUTS + 1], ug[N_INPUTS + 1], uc[N_INPUTS + 1];
    for (int r = 0; r < rows; r++) {
        const long first = (long)r * samples;
        start_row(x0 + r * N_STATES, columns, column, x, S);
        for (int i = 0; i < N_STATES; i++) scale[i] = fabs(x[i]) > 1.0 ? fabs(x[i]) : 1.0;
        emit(first, x, u + first * N_INPUTS, p_, columns, column, S, y, J, states, sens, w.hx, w.hp);
        for (int n = 0; n + 1 < samples; n++) {
            const double h = t[n + 1] - t[n], dh = (h / substeps) * D_COEFFICIENT;
            const double *u0 = u + (first + n) * N_INPUTS, *u1 = u0 + N_INPUTS;
            for (int j = 0; j < substeps; j++) {
                const double fa = (double)j / substeps, fg = (j + GAMMA) / substeps, fc = (double)(j + 1) / substeps;
                stage_inputs(u0, u1, foh, fa, fg, fc, ua, ug, uc);
                rates(t[n] + fa * h, x, ua, p_, f);
                for (int i = 0; i < N_STATES; i++) a[i] = x[i] + dh * f[i];
                if (columns > 0) {
                    stage(t[n] + fa * h, x, ua, p_, columns, column, S, w.K1, w.fx, w.fp);
                    for (int i = 0; i < v; i++) A[i] = S[i] + dh * w.K1[i];
                }
                for (int i = 0; i < N_STATES; i++) middle[i] = x[i];
                if (newton(t[n] + fg * h, ug, p_, a, dh, middle, scale, w.M)) { free(all); return r * samples + n + 1; }
                if (implicit_sensitivities(t[n] + fg * h, middle, ug, p_, dh, columns, column, A, Z, &w)) {
                    free(all); return r * samples + n + 1;
                }
                for (int i = 0; i < N_STATES; i++) a[i] = BDF_NEW * middle[i] - BDF_OLD * x[i];
                for (int i = 0; i < v; i++) A[i] = BDF_NEW * Z[i] - BDF_OLD * S[i];
                for (int i = 0; i < N_STATES; i++) x[i] = middle[i];
                if (newton(t[n] + fc * h, uc, p_, a, dh, x, scale, w.M)) { free(all); return r * samples + n + 1; }
                if (implicit_sensitivities(t[n] + fc * h, x, uc, p_, dh, columns, column, A, S, &w)) {
                    free(all); return r * samples + n + 1;
                }
            }
            const long at = first + n + 1;
            emit(at, x, u1, p_, columns, column, S, y, J, states, sens, w.hx, w.hp);
        }
    }
    free(all);
    return 0;
}
"""


def _torch_like(expression: sympy.Expr) -> sympy.Expr:
    """A derivative as torch takes it: a sign's (a Dirac delta) is 0, a kink's step is 1 on its positive side."""
    expression = expression.replace(sympy.DiracDelta, lambda *args: sympy.S.Zero)
    return expression.replace(sympy.Heaviside, lambda a, *rest: sympy.Piecewise((1, a > 0), (0, True)))


def _derivatives(expressions: list, variables: list, rows: str, width: int) -> dict[str, sympy.Expr]:
    """{``rows[i * width + k]``: d expression_i / d variable_k} for the entries that are not identically zero."""
    entries = {}
    for i, expression in enumerate(expressions):
        free = expression.free_symbols
        for k, variable in enumerate(variables):
            if variable in free:
                derivative = _torch_like(sympy.diff(expression, variable))
                if derivative != 0:
                    entries[f"{rows}[{i * width + k}]"] = derivative
    return entries


def _source(form: _Compiled, n: int, m: int) -> str:
    """The C of ``extend``, ``rates``, ``derivatives`` ($f_x$, $f_\\theta$), ``state_jacobian`` ($f_x$ alone, for
    TR-BDF2's Newton), ``outputs`` ($h$, $h_x$, $h_\\theta$) and :data:`_LOOP`, with the subexpressions of the
    parameters alone lifted into ``extend`` (:func:`~torchpaml._simulate.compiled.extend_function`); the zero entries
    of the derivative arrays are never written (they are zeroed once)."""
    x, p = form.symbols["x"], form.symbols["p"]
    width = max(len(p), 1)
    slopes = _derivatives(form.rates, x, "fx_", n)
    derivatives = {**slopes, **_derivatives(form.rates, p, "fp_", width)}
    jacobian = {f"M_[{i}]": sympy.S.Zero for i in range(n * n)}
    jacobian.update({key.replace("fx_", "M_"): value for key, value in slopes.items()})
    outputs = {f"y_[{o}]": value for o, value in enumerate(form.output)}
    outputs.update({**_derivatives(form.output, x, "hx_", n), **_derivatives(form.output, p, "hp_", width)})
    groups = [form.rates, list(derivatives.values()), list(jacobian.values()), list(outputs.values())]
    (rates, *lifted), fixed = hoisted(groups, variables(form.symbols), len(p))
    derivatives, jacobian, outputs = (dict(zip(d, values, strict=True))
                                      for d, values in zip((derivatives, jacobian, outputs), lifted, strict=True))
    constants = {"GAMMA": GAMMA, "D_COEFFICIENT": D, "BDF_NEW": BDF_NEW, "BDF_OLD": BDF_OLD, "NEWTON_TOL": NEWTON_TOL,
                 "STALL_TOL": STALL_TOL, "MAX_ITERATIONS": MAX_ITERATIONS, "HALVINGS": HALVINGS}
    head = (f"#include <math.h>\n#include <stdlib.h>\n#define N_STATES {n}\n#define N_INPUTS {m}\n"
            f"#define N_OUTPUTS {len(form.output)}\n#define N_PARAMS {width}\n"
            + "".join(f"#define {name} {value!r}\n" for name, value in constants.items()))
    return (head + extend_function(fixed, len(p)) + rates_function(rates)
            + c_function("derivatives", RATES_ARGUMENTS.replace("double *out_", "double *fx_, double *fp_"),
                         derivatives)
            + c_function("state_jacobian", RATES_ARGUMENTS.replace("double *out_", "double *M_"), jacobian)
            + c_function("outputs", "const double *x_, const double *u_, const double *p_, double *y_, double *hx_, "
                         "double *hp_", outputs) + _LOOP)


def _kinked(form: _Compiled) -> bool:
    """Whether the closed form has a kink or a jump (``Max``, ``Min``, ``Abs``, ``sign``, a ``where``): its slopes
    change at once where a state crosses it."""
    kinks = (sympy.Max, sympy.Min, sympy.Abs, sympy.sign, sympy.Piecewise, sympy.Heaviside)
    return any(expression.has(*kinks) for expression in (*form.rates, *form.output))


class _Sensitivities:
    """One physics' compiled ``rk4_rows`` and ``trbdf2_rows`` (module docstring).

    ``kinked``: the physics has a kink (:func:`_kinked`). Its exact Jacobian is the slope on one side of it, which
    vanishes on a clamped side: a fit's trust region, scaled by the Jacobian's columns, then steps without limit
    in that direction (measured on the cascaded tanks, whose levels are clamped at zero: every refit of the third
    rung ran to infinite rates). Fits of such physics take central differences, which see the kink across their
    step, of whole simulations in C (:func:`_differenced`): 2(p + n) + 1 compiled runs, where the engine's
    differences of eager sweeps took 17 s for a kinked tank's fit on 401 samples (0.4 s in C)."""

    def __init__(self, form: _Compiled, n: int, m: int):
        self.kinked = _kinked(form)
        library = loaded(cached_library(_source(form, n, m), "sensitivities", "the compiled Jacobian"))
        self._runs = {name: getattr(library, f"{name}_rows") for name in ("rk4", "trbdf2")}
        for run in self._runs.values():
            run.restype = ctypes.c_int
            run.argtypes = [ctypes.c_int] * 5 + [ctypes.c_void_p] * 9

    def __call__(self, method: str, parameters: np.ndarray, columns: list[int], t: torch.Tensor, u: torch.Tensor,
                 x0: torch.Tensor, outputs: int, substeps: int, hold: str,
                 states: bool = False) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        """Outputs (batch, time, n_output), their Jacobian (batch, time, n_output, columns) and, with ``states``,
        the states (batch, time, n_state) by ``method`` (``"rk4"``, ``"trbdf2"``). Raises
        :class:`~torchpaml.SimulationError` where a TR-BDF2 stage's Newton does not converge, naming the time."""
        batch, samples, _ = u.shape
        y = np.empty((batch, samples, outputs))
        J = np.empty((batch, samples, outputs, len(columns)))
        x = np.empty((batch, samples, x0.shape[-1])) if states else None
        self._run(method, parameters, columns, t, u, x0, substeps, hold, x, y, J, None)
        return torch.from_numpy(y), torch.from_numpy(J), None if x is None else torch.from_numpy(x)

    def sensitive_states(self, method: str, parameters: np.ndarray, columns: list[int], t: torch.Tensor,
                         u: torch.Tensor, x0: torch.Tensor, substeps: int, hold: str
                         ) -> tuple[torch.Tensor, torch.Tensor]:
        """The states (batch, time, n_state) and their sensitivities (batch, time, columns, n_state) to each column
        (module docstring's $S$), by ``method``; raises as :meth:`__call__` does."""
        batch, samples, n = *u.shape[:2], x0.shape[-1]
        x = np.empty((batch, samples, n))
        S = np.empty((batch, samples, len(columns), n))
        self._run(method, parameters, columns, t, u, x0, substeps, hold, x, None, None, S)
        return torch.from_numpy(x), torch.from_numpy(S)

    def _run(self, method: str, parameters: np.ndarray, columns: list[int], t: torch.Tensor, u: torch.Tensor,
             x0: torch.Tensor, substeps: int, hold: str, *written: np.ndarray | None) -> None:
        """``method``'s rows in C, writing the arrays ``written`` (states, outputs, Jacobian, sensitivities; ``None``:
        not asked)."""
        batch, samples, _ = u.shape
        arrays = [np.ascontiguousarray(a.detach().to(torch.float64).numpy()) for a in (t, u, x0)]
        column = np.array(columns, dtype=np.intc)
        code = self._runs[method](batch, samples, substeps, int(hold == "foh"), len(columns), column.ctypes.data,
                                  *[a.ctypes.data for a in arrays], parameters.ctypes.data,
                                  *[None if a is None else a.ctypes.data for a in written])
        if code < 0:
            raise MemoryError("the compiled Jacobian could not allocate its sensitivities")
        if code > 0:
            at = float(t[(code - 1) % samples])
            raise SimulationError(f"TR-BDF2's Newton did not converge in the step from t = {at:.4g} s: the physics is "
                                  f"not smooth enough there, or blows up")


def _columns(form: _Compiled, raw: dict[str, torch.Tensor], n: int, initial_state: bool) -> list[int] | None:
    """Each column's index in the parameter array (a raw parameter, by its ``functional_call`` key), then ``-1 - i``
    for the initial state's ``i``; ``None`` where a parameter is not one scalar of the compiled array."""
    offsets = {name: (first, size) for name, first, size in form.targets}
    columns = []
    for key in raw:
        first, size = offsets.get(key, (None, 0))
        if size != 1:
            return None
        columns.append(first)
    return columns + ([-1 - i for i in range(n)] if initial_state else [])


def compiled_sensitivities(physics: Dynamics, solver: Method) -> tuple[_Compiled, _Sensitivities] | None:
    """The compiled form of ``physics`` and its sensitivities' library, ``None`` where either cannot be had."""
    form = compiled_form(physics, solver)
    if form is None:
        return None
    if form.sensitivities is None:
        try:
            form.sensitivities = _Sensitivities(form, physics.state_dim, physics.input_dim)
        except UnbuildableError as error:
            warn_once(str(error))
            form.sensitivities = False
    return None if form.sensitivities is False else (form, form.sensitivities)


def compiled_jacobian(physics: Dynamics, raw: dict[str, torch.Tensor], t: torch.Tensor, u: torch.Tensor,
                      x0: torch.Tensor, solver: Method, hold: str, initial_state: bool, kinks: bool = False
                      ) -> tuple[torch.Tensor, torch.Tensor] | None:
    """The output (batch, time, n_output) and its Jacobian (batch, time, n_output, p [+ n_state]) in the raw
    parameters ``raw`` (and ``x0`` (batch, n_state) with ``initial_state``) by ``solver``'s method (RK4, TR-BDF2) at
    its substeps in C (module docstring): for a physics with a kink, central differences of compiled simulations
    unless ``kinks`` asks for the exact one-sided slopes (:class:`_Sensitivities`); ``None`` where it is left to the
    shooting engine: another method, a physics that does not compile
    (:func:`~torchpaml._simulate.compiled.compiled_form`), a parameter that is not one scalar, or a Jacobian that is
    not finite (one progress line says so). Raises :class:`~torchpaml.SimulationError` where the output blows up
    (:func:`~torchpaml._simulate.blowup.checked_output`, as the engine does, without its slower way there), where a
    TR-BDF2 stage's Newton fails (a fit rejects the point, as it does where the engine's fails: one arithmetic path
    per fit, never the engine's slower Newton on the points where C's gave up), or where both sides of a difference
    fail (:func:`_difference`)."""
    compiled = compiled_sensitivities(physics, solver) if len(t) > 1 else None
    if compiled is None:
        return None
    form, run = compiled
    columns = _columns(form, raw, physics.state_dim, initial_state)
    if columns is None:
        return None
    simulate = functools.partial(run, solver.compiles, outputs=physics.output_dim, substeps=solver.substeps, hold=hold)
    if run.kinked and not kinks:
        done = _differenced(simulate, form.parameters(physics), columns, t, u, x0)  # its output checked there
    else:
        done = simulate(form.parameters(physics), columns, t, u, x0)
        checked_output(done[0], t)  # raises where the output blows up, naming the time, as the engine does
    if not bool(torch.isfinite(done[1]).all()):
        log.info("%s: the compiled Jacobian is not finite at these parameters; the torch engine's differences give "
                 "this one", physics.display_name)
        return None
    return done[0].to(x0.dtype), done[1].to(x0.dtype)


def _differenced(simulate: Callable, parameters: np.ndarray, columns: list[int], t: torch.Tensor, u: torch.Tensor,
                 x0: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    r"""The outputs and their Jacobian by central differences of whole compiled simulations (a kinked physics,
    :class:`_Sensitivities`): each column $(\hat y(\theta + s e_j) - \hat y(\theta - s e_j))/2s$ with the steps
    of the engine's differences (:func:`~torchpaml._simulate.differences.difference_step` of $\rho_j$, of
    $\max|x_0|$ for an initial state's), 2(p + n) + 1 runs in C.

    Where one side fails or blows up (:func:`_difference`), the column is the other side's one-sided difference."""
    def output(p: np.ndarray, x: torch.Tensor) -> torch.Tensor:
        return simulate(p, [], t, u, x)[0]

    def side(p: np.ndarray, x: torch.Tensor) -> torch.Tensor | None:
        try:
            return output(p, x)
        except SimulationError:  # a side's TR-BDF2 Newton failed: the other side's difference
            return None

    y = output(parameters, x0)
    checked_output(y, t)  # raises where the output itself blows up, naming the time
    state_step = difference_step(float(x0.detach().abs().max()))
    differences = []
    for column in columns:
        if column >= 0:
            step = difference_step(float(parameters[column]))
            up, down = parameters.copy(), parameters.copy()
            up[column] += step
            down[column] -= step
            sides = side(up, x0), side(down, x0)
        else:
            step = state_step
            direction = torch.zeros_like(x0)
            direction[..., -1 - column] = step
            sides = side(parameters, x0 + direction), side(parameters, x0 - direction)
        differences.append(_difference(y, sides, step))
    J = torch.stack(differences, dim=-1) if differences else y.new_zeros(*y.shape, 0)
    return y, J


def _difference(y: torch.Tensor, sides: tuple[torch.Tensor | None, torch.Tensor | None], step: float) -> torch.Tensor:
    r"""One column: the central difference $(\hat y_+ - \hat y_-)/2s$ of the two sides; where one side fails (its
    TR-BDF2 Newton, ``None``) or blows up (beyond the engine's bound, :data:`~torchpaml._simulate.blowup.BLOWUP`)
    while the output does not, the parameters sit at the edge of the step's stability and the column is the other
    side's one-sided difference (the slope on the side the step resolves). On the cascaded tanks such a side reached
    ~1e250, and the central column of 6e256 it gave overflowed the trust region's scaling into NaN unknowns. Raises
    :class:`~torchpaml.SimulationError` where both sides fail."""
    up, down = (side is None or bool(blown_up(side).any()) for side in sides)
    if not (up or down):
        return (sides[0] - sides[1]) / (2 * step)
    if up and down:
        raise SimulationError("both sides of the Jacobian's central difference failed or blew up where the output did "
                              "not: the parameters sit at the edge of the step's stability (raise substeps, or use "
                              "solver=TRBDF2() for stiff physics)")
    return (y - sides[1]) / step if up else (sides[0] - y) / step


def compiled_states(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, solver: Method,
                    hold: str) -> torch.Tensor | None:
    """The states (batch, time, n_state) of ``physics`` from ``x0`` (batch, n_state) driven by ``u`` (batch, time,
    n_input) on ``t`` (time,) by ``solver``'s method in C, detached: RK4
    (:func:`~torchpaml._simulate.compiled.sequential_states`, long records) or TR-BDF2 (:func:`implicit_states`, any
    length); ``None`` where the shooting engine simulates."""
    if solver.compiles == "trbdf2":
        return _finite(implicit_states(physics, t, u, x0, solver, hold))
    return sequential_states(physics, t, u, x0, solver, hold)


def _finite(states: torch.Tensor | None) -> torch.Tensor | None:
    return states if states is not None and bool(torch.isfinite(states).all()) else None


def implicit_states(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, solver: Method,
                    hold: str) -> torch.Tensor | None:
    """The states (batch, time, n_state) by TR-BDF2 at ``solver.substeps`` in C, as
    :func:`~torchpaml._simulate.compiled.sequential_states` gives RK4's; ``None`` where it is left to the engine."""
    compiled = compiled_sensitivities(physics, solver)
    if compiled is None:
        return None
    form, run = compiled
    try:
        done = run("trbdf2", form.parameters(physics), [], t, u, x0, physics.output_dim, solver.substeps, hold,
                   states=True)
    except SimulationError as error:
        log.info("%s: %s in C; the torch engine simulates this one", physics.display_name, error)
        return None
    return done[2].to(x0.dtype)
