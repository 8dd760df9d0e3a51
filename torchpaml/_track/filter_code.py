r"""The extended Kalman filter of a model, as C printed from its closed form and compiled once per model.

**Prediction** from sample $k$ to $k+1$: the model's RK4 step $\Phi$ (:func:`~torchpaml._export.code.c_code`) and
its Jacobian $F = \partial\Phi/\partial x$, obtained by the same RK4 stages applied to the variational equation
$\dot F = J(t, x, u) F$ with $J = \partial f/\partial x$ printed from the closed form (exact for the discrete step):

$$ \hat x^-_{k+1} = \Phi(\hat x_k), \qquad P^-_{k+1} = F P_k F^\top + Q. $$

**Update** at each sample with $H = \partial h/\partial x$: the innovation $e = y - h(\hat x^-, u)$, its covariance
$S = H P^- H^\top + R$, the gain $K = P^- H^\top S^{-1}$ (a Cholesky solve), $\hat x = \hat x^- + K e$ and the
Joseph form $P = (I - KH) P^- (I - KH)^\top + K R K^\top$. The normalised innovation squared
$\nu = e^\top S^{-1} e$ (chi-squared with $p$ degrees of freedom while the device matches the model) feeds the
change detector (:mod:`~torchpaml._track.tracker`).

**A missing measurement** (a NaN in any output of a sample) is predicted through: no update, the innovation NaN
and $\nu = 0$, so the detector's window sum holds no term for it.

One call filters a block of samples in C (``track_block``); the filter's state (x, P) lives in numpy arrays the
caller keeps, so a stream is fed one sample or a thousand at a time with the same result.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np
import sympy
from sympy.printing.c import C99CodePrinter

from torchpaml._export.code import ExportedStep, c_code, c_unpacking
from torchpaml._simulate.compiled import PRODUCTS
from torchpaml._symbolic.compiler import cached_library, loaded

__all__ = ["CompiledFilter", "compiled_filter", "filter_source"]

_KALMAN = r"""
static void jacobian_of_step(double t, const double *x, const double *u0, const double *u1, double h,
                             double *x_next, double *F) {
    double slope[N_INPUTS], ua[N_INPUTS], um[N_INPUTS], uc[N_INPUTS];
    double z[N_STATES], k[4][N_STATES], J[N_STATES * N_STATES], G[4][N_STATES * N_STATES], Fz[N_STATES * N_STATES];
    const double d = h / SUBSTEPS;
    double X[N_STATES];
    for (int i = 0; i < N_STATES; i++) X[i] = x[i];
    for (int i = 0; i < N_STATES * N_STATES; i++) F[i] = (i % (N_STATES + 1) == 0) ? 1.0 : 0.0;
    for (int i = 0; i < N_INPUTS; i++) slope[i] = HOLD_FOH ? (u1[i] - u0[i]) / h : 0.0;
    static const double stage_step[4] = {0.0, 0.5, 0.5, 1.0};
    for (int j = 0; j < SUBSTEPS; j++) {
        const double a = t + j * d;
        for (int i = 0; i < N_INPUTS; i++) {
            ua[i] = u0[i] + slope[i] * (a - t);
            um[i] = u0[i] + slope[i] * (a + d / 2 - t);
            uc[i] = u0[i] + slope[i] * (a + d - t);
        }
        for (int s = 0; s < 4; s++) {
            const double c = stage_step[s] * d;
            const double *us = s == 0 ? ua : (s == 3 ? uc : um);
            for (int i = 0; i < N_STATES; i++) z[i] = X[i] + (s ? c * k[s - 1][i] : 0.0);
            for (int i = 0; i < N_STATES * N_STATES; i++) Fz[i] = F[i] + (s ? c * G[s - 1][i] : 0.0);
            derivative(a + c, z, us, k[s]);
            rate_jacobian(a + c, z, us, J);
            for (int r = 0; r < N_STATES; r++)
                for (int q = 0; q < N_STATES; q++) {
                    double acc = 0.0;
                    for (int l = 0; l < N_STATES; l++) acc += J[r * N_STATES + l] * Fz[l * N_STATES + q];
                    G[s][r * N_STATES + q] = acc;
                }
        }
        for (int i = 0; i < N_STATES; i++) X[i] += d / 6 * (k[0][i] + 2 * k[1][i] + 2 * k[2][i] + k[3][i]);
        for (int i = 0; i < N_STATES * N_STATES; i++) F[i] += d / 6 * (G[0][i] + 2 * G[1][i] + 2 * G[2][i] + G[3][i]);
    }
    for (int i = 0; i < N_STATES; i++) x_next[i] = X[i];
}

/* Cholesky solve of S X = B in place (S: p x p symmetric positive definite, B: p x c); 0 on success */
static int cholesky_solve(int p, double *S, double *B, int c) {
    for (int j = 0; j < p; j++) {
        double s = S[j * p + j];
        for (int l = 0; l < j; l++) s -= S[j * p + l] * S[j * p + l];
        if (!(s > 0.0)) return 1;
        S[j * p + j] = sqrt(s);
        for (int i = j + 1; i < p; i++) {
            double v = S[i * p + j];
            for (int l = 0; l < j; l++) v -= S[i * p + l] * S[j * p + l];
            S[i * p + j] = v / S[j * p + j];
        }
    }
    for (int col = 0; col < c; col++) {
        for (int i = 0; i < p; i++) {
            double v = B[i * c + col];
            for (int l = 0; l < i; l++) v -= S[i * p + l] * B[l * c + col];
            B[i * c + col] = v / S[i * p + i];
        }
        for (int i = p - 1; i >= 0; i--) {
            double v = B[i * c + col];
            for (int l = i + 1; l < p; l++) v -= S[l * p + i] * B[l * c + col];
            B[i * c + col] = v / S[i * p + i];
        }
    }
    return 0;
}

/* Filter samples start..n-1 of (t, u, y); x (N_STATES) and P (N_STATES^2) carry the filter from sample start - 1
   (or hold the prior at sample 0 when start == 0). Writes each sample's innovation (N_OUTPUTS), its normalised
   square nis and the filtered state. Returns 0, k + 1 where S stopped being positive definite at sample k, or
   -(k + 1) where sample k's input is not finite. */
int track_block(int n, int start, const double *t, const double *u, const double *y, double *x, double *P,
                const double *Q, const double *R, double *innovation, double *nis, double *states) {
    const int N = N_STATES, p = N_OUTPUTS;
    double F[N_STATES * N_STATES], FP[N_STATES * N_STATES], xn[N_STATES], yh[N_OUTPUTS], H[N_OUTPUTS * N_STATES];
    double S[N_OUTPUTS * N_OUTPUTS], HP[N_OUTPUTS * N_STATES], Kt[N_OUTPUTS * N_STATES], A[N_STATES * N_STATES];
    double e[N_OUTPUTS], w[N_OUTPUTS], AP[N_STATES * N_STATES];
    for (int k = start; k < n; k++) {
        for (int i = 0; i < N_INPUTS; i++) if (!isfinite(u[k * N_INPUTS + i])) return -(k + 1);
        if (k > 0) {
            jacobian_of_step(t[k - 1], x, u + (k - 1) * N_INPUTS, u + k * N_INPUTS, t[k] - t[k - 1], xn, F);
            for (int i = 0; i < N; i++) x[i] = xn[i];
            for (int r = 0; r < N; r++) for (int q = 0; q < N; q++) {
                double acc = 0.0; for (int l = 0; l < N; l++) acc += F[r * N + l] * P[l * N + q]; FP[r * N + q] = acc; }
            for (int r = 0; r < N; r++) for (int q = 0; q < N; q++) {
                double acc = Q[r * N + q]; for (int l = 0; l < N; l++) acc += FP[r * N + l] * F[q * N + l];
                P[r * N + q] = acc; }
        }
        int missing = 0;
        for (int i = 0; i < p; i++) missing |= isnan(y[k * p + i]);
        if (missing) {  /* a missing measurement: the prediction stands, no update, nothing for the detector */
            for (int i = 0; i < p; i++) innovation[k * p + i] = NAN;
            nis[k] = 0.0;
            for (int i = 0; i < N; i++) states[k * N + i] = x[i];
            continue;
        }
        output(x, u + k * N_INPUTS, yh);
        output_jacobian(x, u + k * N_INPUTS, H);
        for (int i = 0; i < p; i++) e[i] = y[k * p + i] - yh[i];
        for (int i = 0; i < p; i++) for (int q = 0; q < N; q++) {
            double acc = 0.0; for (int l = 0; l < N; l++) acc += H[i * N + l] * P[l * N + q]; HP[i * N + q] = acc; }
        for (int i = 0; i < p; i++) for (int j = 0; j < p; j++) {
            double acc = R[i * p + j]; for (int l = 0; l < N; l++) acc += HP[i * N + l] * H[j * N + l];
            S[i * p + j] = acc; }
        for (int i = 0; i < p * N; i++) Kt[i] = HP[i];
        for (int i = 0; i < p; i++) w[i] = e[i];
        double Sc[N_OUTPUTS * N_OUTPUTS];
        for (int i = 0; i < p * p; i++) Sc[i] = S[i];
        if (cholesky_solve(p, Sc, Kt, N)) return k + 1;
        for (int i = 0; i < p * p; i++) Sc[i] = S[i];
        cholesky_solve(p, Sc, w, 1);
        double v = 0.0;
        for (int i = 0; i < p; i++) v += e[i] * w[i];
        for (int i = 0; i < N; i++) { double acc = 0.0; for (int j = 0; j < p; j++) acc += Kt[j * N + i] * e[j]; x[i] += acc; }
        for (int r = 0; r < N; r++) for (int q = 0; q < N; q++) {
            double acc = (r == q) ? 1.0 : 0.0; for (int j = 0; j < p; j++) acc -= Kt[j * N + r] * H[j * N + q];
            A[r * N + q] = acc; }
        for (int r = 0; r < N; r++) for (int q = 0; q < N; q++) {
            double acc = 0.0; for (int l = 0; l < N; l++) acc += A[r * N + l] * P[l * N + q]; AP[r * N + q] = acc; }
        for (int r = 0; r < N; r++) for (int q = 0; q < N; q++) {
            double acc = 0.0;
            for (int l = 0; l < N; l++) acc += AP[r * N + l] * A[q * N + l];
            for (int i = 0; i < p; i++) for (int j = 0; j < p; j++) acc += Kt[i * N + r] * R[i * p + j] * Kt[j * N + q];
            FP[r * N + q] = acc; }
        for (int i = 0; i < N * N; i++) P[i] = FP[i];
        for (int i = 0; i < p; i++) innovation[k * p + i] = e[i];
        nis[k] = v;
        for (int i = 0; i < N; i++) states[k * N + i] = x[i];
    }
    return 0;
}
"""


def _matrix_function(name: str, signature: str, matrix: sympy.Matrix, step: ExportedStep) -> str:
    printer = C99CodePrinter()
    matrix = matrix.applyfunc(lambda e: e.rewrite(sympy.Piecewise) if e.has(sympy.Heaviside) else e)
    unpack = c_unpacking(step.form)
    body = "".join(f"    out_[{i}] = {printer.doprint(PRODUCTS(value))};\n" for i, value in enumerate(matrix))
    return f"static void {name}({signature}) {{\n    (void)state_; (void)input_;\n{unpack}{body}}}\n"


def filter_source(step: ExportedStep) -> str:
    """The C of the filter (module docstring)."""
    form = step.form
    J = sympy.Matrix(form.rates).jacobian(form.states)
    H = sympy.Matrix(form.output).jacobian(form.states)
    rates = _matrix_function("rate_jacobian", f"double {form.time.name}, const double *state_, const double *input_, "
                             "double *out_", J, step).replace("(void)state_;", f"(void){form.time.name}; (void)state_;")
    output = _matrix_function("output_jacobian", "const double *state_, const double *input_, double *out_", H, step)
    return (c_code(step) + f"#define HOLD_FOH {int(step.hold == 'foh')}\n" + rates + output + _KALMAN)


class CompiledFilter:
    """The compiled ``track_block`` of one model (module docstring), with its sizes."""

    def __init__(self, library: Path, states: int, inputs: int, outputs: int):
        self.states, self.inputs, self.outputs = states, inputs, outputs
        self._library = loaded(library)
        self._run = self._library.track_block
        self._run.restype = ctypes.c_int
        self._run.argtypes = [ctypes.c_int, ctypes.c_int] + [ctypes.c_void_p] * 10

    def run_into(self, start: int, arrays: tuple[np.ndarray, ...]) -> int:
        """``track_block`` on ``arrays`` = (t, u, y, x, P, Q, R, innovation, nis, states), C-contiguous float64, the
        outputs written in place; returns the C's status (module docstring). The caller checks the arrays."""
        return self._run(len(arrays[0]), start, *[a.ctypes.data for a in arrays])

    def run_at_addresses(self):
        """The C function itself, called as ``run(samples, start, *addresses)``: :meth:`run_into` on arrays given by
        their addresses, for a caller that keeps its arrays and calls once per sample."""
        return self._run


def compiled_filter(step: ExportedStep) -> CompiledFilter:
    """The filter of ``step`` compiled (once per machine: :func:`~torchpaml._symbolic.compiler.cached_library`), loaded."""
    library = cached_library(filter_source(step), "filter", "tracking")
    form = step.form
    return CompiledFilter(library, len(form.states), len(form.inputs), len(form.outputs))
