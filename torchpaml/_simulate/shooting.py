r"""Fixed-step methods on the sample grid, parallel in time: multiple shooting with Newton on the segment starts.

**Why.** Eager PyTorch pays a dispatch cost of a few microseconds per operation, and an RK4 step of a
small ODE is about a hundred operations, so a sample-by-sample loop costs the same per sample whether
it carries 1 row or 1000. The cost is the number of *sequential* steps, so this engine makes them few.

**The step.** Between samples $t_k$ and $t_{k+1}$ ($h_k = t_{k+1} - t_k$, any spacing) the input is the
first-order hold $u(\tau) = u_k + (\tau - t_k)(u_{k+1} - u_k)/h_k$ (or, with ``hold="zoh"``, $u_k$
held), the hold the exact LTI path assumes. ``substeps`` steps of $h_k/m$ of the solver's method
(:mod:`~torchpaml._simulate.steps`: classical RK4, global error $O(h^4)$, tested: halving $h$ divides it
by 16; or the implicit TR-BDF2, $O(h^2)$, for stiff physics) advance the state.

**Multiple shooting.** The $N - 1$ steps are cut into $S$ segments of $L$ steps. From guesses $\xi_s$ of
the state at the segment starts, all segments are integrated at once, one batch row each, together
with $2n$ rows started at $\xi_s \pm \delta_i e_i$. These give every state $x_{s,k}$ of the segment, its end
$e_s(\xi_s)$, and by central differences the sensitivities $T_{s,k} = \partial x_{s,k}/\partial\xi_s$ (error
$O(\delta^2)$, $\delta_i = 10^{-5}$ times the scale of state $i$), the end's $G_s = T_{s,L}$ among them.
Newton's method on the continuity defects $e_s(\xi_s) - \xi_{s+1} = 0$ updates every start at once:

$$ \xi^{+}_0 = x_0, \qquad \xi^{+}_{s+1} = e_s + G_s\,(\xi^{+}_s - \xi_s), $$

a linear recurrence solved by a parallel scan (:func:`~torchpaml._simulate.scan.linear_recurrence`).
After $j$ sweeps the first $j$ starts are exact, so the iteration ends after at most $S$ sweeps; for a
smooth, stable system it converges quadratically, in a few. A sweep costs $L$ sequential steps on
$B \cdot S \cdot (2n + 1)$ rows. This is parallel-in-time Newton (DEER, Lim et al. 2024) applied to
segments rather than single steps: inside a segment the integration stays nonlinear, which is what
keeps Newton from diverging when a cubic term dominates.

**Start and cost.** Newton starts from a nearby solution when the caller has one (a fit's previous
iterate, a training run's previous step: ``warm``), else from the exact trajectory of the model's
linear base (:func:`linear_guess`), else from $x_0$ held. Its sweeps take forward differences (n + 1
rows per segment) until the defects are small, then central ones (2n + 1). The stage times and inputs
of every step are laid out once per solve, the states are kept state-major (each state's column
contiguous: :func:`~torchpaml.state_vector`), and each RK4 stage is one fused ``addcmul``, so an
RK4 step costs little more than its four calls of the physics.

**Gradients** (reverse and forward mode) come from the implicit function theorem. With the converged
starts $\xi^*$ held fixed, one differentiable sweep gives $x_{s,k}(\xi^*_s;\theta)$ and $e_s(\theta)$. The
starts' drift obeys $\delta\xi_{s+1} = G_s\,\delta\xi_s + (e_s(\theta) - \xi^*_{s+1})$, $\delta\xi_0 = x_0 - \xi^*_0$:
the same scan, applied to the continuity defects (zero at convergence, up to Newton's tolerance), so
that $x_{s,k} + T_{s,k}\,\delta\xi_s$ has the converged value and the exact total derivative. Being a
function of values, not a stop-gradient trick, it also serves central differences in $\theta$ and
$x_0$: one linearised Newton step at the perturbed point, error $O(\delta^2)$, which cancels in the
central difference to $O(\delta^2)$ as well.
"""

from __future__ import annotations

import math
import torch
from torch.nn.utils import parametrize

from torchpaml._simulate.compiled_gradient import compiled_gradient_states, constants
from torchpaml._simulate.compiled_jacobian import compiled_states
from torchpaml._simulate.dynamics import Dynamics
from torchpaml._simulate.method import Method
from torchpaml._errors import ConfigurationError, SimulationError
from torchpaml._budget import checkpoint
from torchpaml._grid import check_hold
from torchpaml._simulate.lti import exact_step, simulate_lti_states
from torchpaml._simulate.scan import linear_recurrence
from torchpaml._simulate.second_order import one_segment, with_second_order
from torchpaml._simulate.warm import WarmStart


__all__ = ["ShootingSolution", "base_guess", "simulate_shooting", "solve_shooting"]
#: Relative size of the start perturbations of the central differences (the sweep that feeds gradients).
PERTURBATION = 1e-5
#: Relative size of the start perturbations of the forward differences (Newton's G).
FORWARD_PERTURBATION = 1e-7
#: Rows per sweep above which segments are lengthened: larger tensors leave the CPU cache.
CACHE_ROWS = 32768
#: Memory up to which a layout keeps the per-step stage times and inputs of its sweeps (repeated per copy).
STAGE_BYTES = 64 * 2**20
#: Newton's stopping defect (relative to the state's scale) for values: the last update is applied linearly,
#: which leaves an error O(defect^2), ~1e-14 (measured).
NEWTON_TOL = 1e-7
#: The stopping defect of a solve whose sensitivities feed derivatives, whose error is O(defect).
GRADIENT_TOL = 1e-9
#: Defect below which Newton's next sweep is expected to converge (quadratic convergence squares it), so
#: it takes the central differences whose T feeds gradients.
GRADED_DEFECT = 1e-3
#: Factor by which the segments lengthen when Newton does not converge in ``max_sweeps`` sweeps.
GROWTH = 8
#: Largest Newton step of a start beyond the exact prefix, in units of the state's scale.
TRUST = 0.25


class _Layout:
    """The record cut into S segments of L steps, padded at the end with steps of length 0."""

    def __init__(self, t: torch.Tensor, u: torch.Tensor, solver: Method, segment: int, hold: str = "foh"):
        batch, N, m = u.shape
        steps = N - 1
        segment = max(segment, math.ceil(batch * steps * 3 / CACHE_ROWS))
        self.L = max(1, min(segment, steps))
        self.S = math.ceil(steps / self.L)
        pad = self.S * self.L - steps
        self.batch, self.N, self.solver = batch, N, solver
        substeps = solver.substeps
        h = torch.cat([torch.diff(t), t.new_zeros(pad)]).reshape(self.S, self.L).t()  # (L, S)
        t0 = torch.cat([t[:-1], t[-1:].expand(pad)]).reshape(self.S, self.L).t()
        u0 = torch.cat([u[:, :-1], u[:, -1:].expand(batch, pad, m)], dim=1)
        u1 = torch.cat([u[:, 1:], u[:, -1:].expand(batch, pad, m)], dim=1)
        # every stage's time and input (L, 2 substeps + 1, rows, ...) at the fractions j / substeps and
        # (j + middle) / substeps, and the method's step coefficients times the substep (L, k, S, 1); the time and
        # the steps are shared by the batch
        points = (torch.arange(substeps, dtype=t.dtype)[:, None] + torch.tensor([0.0, solver.middle], dtype=t.dtype))
        fractions = torch.cat([points.flatten(), torch.tensor([float(substeps)], dtype=t.dtype)]) / substeps
        self._times = t0[:, None] + fractions[:, None] * h[:, None]
        rows = lambda v: v.reshape(batch * self.S, self.L, m).transpose(0, 1)  # noqa: E731  (L, batch * S, m)
        start, change = rows(u0), rows(u1 - u0 if hold == "foh" else torch.zeros_like(u0))
        self._inputs = start[:, None] + fractions[:, None, None] * change[:, None]
        coefficients = torch.tensor(solver.coefficients, dtype=t.dtype)
        self._steps = (h / substeps)[:, None, :, None] * coefficients[:, None, None]
        self._stages: dict[int, list] = {}

    def stages(self, copies: int):
        """Per step, for ``copies`` stacked blocks of batch * S rows: the stage times (a tuple of 2 substeps + 1
        of (rows,)), the inputs ((rows, m) each), and the half, whole and sixth substep ((rows, 1) each).

        Kept for the next sweep with as many copies when they take less than :data:`STAGE_BYTES` and carry
        no gradient (an input that requires one is differentiated through a fresh graph every sweep)."""
        graph = torch.is_grad_enabled() and self._inputs.requires_grad
        if copies in self._stages and not graph:
            return self._stages[copies]
        shared = copies * self.batch
        stages = ((times.repeat(1, shared).unbind(0), inputs.repeat(1, copies, 1).unbind(0),
                   steps.repeat(1, shared, 1).unbind(0))
                  for times, inputs, steps in zip(self._times, self._inputs, self._steps))
        size = copies * (self._times.numel() * self.batch + self._inputs.numel() + self._steps.numel() * self.batch)
        if graph or size * self._inputs.element_size() > STAGE_BYTES:
            return stages
        self._stages[copies] = list(stages)
        return self._stages[copies]

    def sweep(self, physics: Dynamics, starts: torch.Tensor, copies: int = 1) -> torch.Tensor:
        """starts (copies, batch, S, n) -> states (copies, batch, S, L + 1, n), a view of state-major memory."""
        n = starts.shape[-1]
        states = self.solver.sweep(physics, starts.reshape(-1, n), self.stages(copies))
        return states.reshape(n, self.L + 1, copies, self.batch, self.S).permute(2, 3, 4, 1, 0)

    def assemble(self, states: torch.Tensor) -> torch.Tensor:
        """Segment states (batch, S, L + 1, n) -> the record's states (batch, N, n)."""
        n = states.shape[-1]
        body = states[:, :, : self.L].reshape(self.batch, self.S * self.L, n)
        return torch.cat([body, states[:, -1:, self.L]], dim=1)[:, : self.N]

    def time_of_segment(self, s: int) -> float:
        return float(self._times[0, 0, s])


class _Sweep:
    """One sweep from the starts and from the starts perturbed along each state, whose differences give the
    sensitivities T = d states / d start.

    ``central``: central differences (2n extra rows, error ~1e-10), for the sweep whose T feeds
    gradients; otherwise forward differences (n extra rows, error ~1e-7), enough for Newton's G.
    """

    def __init__(self, physics: Dynamics, layout: _Layout, starts: torch.Tensor, scale: torch.Tensor,
                 central: bool):
        n = starts.shape[-1]
        self.n, self.central = n, central
        self.delta = (PERTURBATION if central else FORWARD_PERTURBATION) * scale
        signs = [torch.diag(self.delta), -torch.diag(self.delta)] if central else [torch.diag(self.delta)]
        offsets = torch.cat([torch.zeros(1, n, dtype=starts.dtype), *signs])
        with parametrize.cached():
            self.states = layout.sweep(physics, starts[None] + offsets[:, None, None, :], copies=len(offsets))

    @property
    def centre(self) -> torch.Tensor:
        """The states from the starts themselves, (batch, S, L+1, n)."""
        return self.states[0]

    def sensitivities(self, step: int | None = None) -> torch.Tensor:
        """T (batch, S, L+1, n, n), or at one ``step`` of every segment (batch, S, n, n) (-1: G, at the ends)."""
        states = self.states.detach() if step is None else self.states[:, :, :, step].detach()
        n = self.n
        low = states[n + 1 :] if self.central else states[:1]
        scale = (2 if self.central else 1) * self.delta.reshape(n, *[1] * (states.dim() - 1))
        return ((states[1 : n + 1] - low) / scale).movedim(0, -1)


def _trusted(ends: torch.Tensor, updated: torch.Tensor, scale: torch.Tensor, x0: torch.Tensor) -> torch.Tensor:
    r"""The next starts: each segment's nonlinear end plus its Newton correction, clipped to ``TRUST`` scales.

    Newton's start is $\xi^+_{s+1} = e_s + G_s(\xi^+_s - \xi_s)$. Far from the solution the linear correction
    $G_s(\xi^+_s - \xi_s)$ can overshoot into states the dynamics never reach (where a cubic term makes
    RK4 itself unstable), so each component is clipped to ``TRUST`` times the state's scale; $e_s$ is
    the ODE's own propagation and stays plausible. On the exact prefix the correction is 0, so the
    first ``sweep`` starts stay exact; near the solution nothing is clipped and convergence stays
    quadratic. A segment that blew up from a wrong start hands $x_0$ to the next one.
    """
    limit = TRUST * scale
    correction = (updated[:, 1:] - ends[:, :-1]).nan_to_num(0.0, 0.0, 0.0).clamp(-limit, limit)
    following = torch.where(torch.isfinite(ends[:, :-1]), ends[:, :-1] + correction, x0[:, None])
    return torch.cat([x0[:, None], following], dim=1)


def _newton(physics: Dynamics, layout: _Layout, x0: torch.Tensor, tol: float, max_sweeps: int,
            differentiable: bool, guess: torch.Tensor | None, settled: bool = False):
    r"""Newton on the segment starts (module docstring), from ``guess``'s states at the starts if it is finite,
    else from $x_0$ held; ``settled``: the guess is the solution (the compiled RK4's,
    :mod:`~torchpaml._simulate.compiled`), so the first sweep is already graded.

    A sweep takes forward differences (n + 1 copies) until the defects fall below :data:`GRADED_DEFECT`;
    from then on, when ``differentiable``, central ones (2n + 1 copies), whose T feeds gradients.

    Newton stops at the first sweep whose continuity defects are below ``tol`` (relative to the states'
    scale; quadratic convergence takes them from ~1e-4 to ~1e-8 in one sweep) and that is graded when
    ``differentiable``. Its last update is applied to the states linearly, $x + T\,\Delta\xi$ (error
    $O(|\Delta\xi|^2)$, ~1e-14 relative at 1e-7, measured), which saves the sweep that would confirm it.

    A segment that blows up (a non-finite state) from a settled start, one of the first ``sweep`` (exact after
    as many sweeps) or one that every earlier segment's end meets within ``tol`` (:func:`_settled`), is the
    solution's own blow-up: it raises :class:`~torchpaml.SimulationError` at once. Where the
    parameters are unstable, Newton settles the record up to the blow-up in a few sweeps; lengthening the
    segments instead (:data:`GROWTH`) would end in sequential stepping through the whole record first
    (a ranking's trial step on 10^6 samples, one thread: 424 s that way, 1.9 s from the settled starts).

    Returns those states (batch, S, L+1, n) and, when ``differentiable``, T and the starts of the last
    sweep (:meth:`ShootingSolution.states` applies the same update, differentiably).
    """
    warm = guess is not None and guess.shape[:2] == (x0.shape[0], layout.N) and bool(torch.isfinite(guess).all())
    if warm:
        starts = torch.cat([x0[:, None], guess[:, layout.L : (layout.S - 1) * layout.L + 1 : layout.L]], dim=1)
    else:
        starts = x0[:, None].expand(-1, layout.S, -1).clone()
    scale = x0.abs().amax(dim=0).clamp(min=1.0)
    defect = 0.0 if layout.S == 1 or (settled and warm) else math.inf  # one segment: its start is x0, exact
    for sweep in range(1, max_sweeps + 1):
        checkpoint()  # a fit's budget (torchpaml._budget) stops a solve that does not settle
        graded = differentiable and defect <= GRADED_DEFECT
        result = _Sweep(physics, layout, starts, scale, central=graded)
        ends = result.centre[:, :, -1].detach()  # (batch, S, n); a state that blew up leaves its end non-finite
        finite = torch.isfinite(ends).all(dim=2).all(dim=0)  # (S,)
        magnitude = ends.nan_to_num(0.0, 0.0, 0.0).abs().amax(dim=(0, 1))
        scale = torch.where(torch.isfinite(magnitude) & (magnitude > 0), magnitude, scale)
        gaps = (ends[:, :-1] - starts[:, 1:]).abs()  # (batch, S - 1, n)
        if not bool(finite[:max(sweep, _settled(gaps, ends, tol))].all()):  # from settled starts: a true blow-up
            s = int((~finite).nonzero()[0])
            raise SimulationError(
                f"the {type(layout.solver).__name__} simulation blew up (non-finite state) in the segment starting at "
                f"t = {layout.time_of_segment(s):.4g} s; the parameters are probably unstable or unphysical (e.g. "
                "negative damping), or the step is too long for the dynamics (raise substeps, or use solver=TRBDF2() "
                "for stiff physics)"
            )
        defect = float((gaps / scale).nan_to_num(math.inf).max()) if layout.S > 1 else 0.0
        G = result.sensitivities(-1)
        shift = ends[:, :-1] - (G[:, :-1] @ starts[:, :-1, :, None])[..., 0]
        updated = linear_recurrence(G[:, :-1], shift, x0)
        if defect <= tol and (graded or not differentiable):
            T = result.sensitivities()
            states = result.centre.detach() + (T @ (updated - starts)[:, :, None, :, None])[..., 0]
            return (states, T, starts) if differentiable else (states, None, None)
        starts = _trusted(ends, updated, scale, x0)
    raise _NotConverged(layout.assemble(result.centre.detach()))


def _settled(gaps: torch.Tensor, ends: torch.Tensor, tol: float) -> int:
    """How many leading segments start from a settled state: the first (from $x_0$) and each next one while the
    previous segment's end meets its start within ``tol``.

    ``gaps`` (batch, S - 1, n): |end of segment s - start of s + 1|; ``ends`` (batch, S, n). Each gap is taken
    relative to the largest end up to its own segment (1 where that is 0), not to the whole record's: segments
    further on that run away from a wrong start must not make an early gap look small."""
    magnitude = ends[:, :-1].abs().amax(dim=0).nan_to_num(math.inf, math.inf, math.inf)  # (S - 1, n)
    running = torch.cummax(magnitude, dim=0).values if len(magnitude) else magnitude
    relative = (gaps / torch.where(running > 0, running, 1.0)).nan_to_num(math.inf).amax(dim=(0, 2))
    unsettled = (relative > tol).nonzero()
    return 1 + (int(unsettled[0]) if len(unsettled) else len(relative))


def linear_guess(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, hold: str = "foh"
                 ) -> torch.Tensor | None:
    r"""The states (batch, time, n) of the model's linear base (:meth:`~torchpaml.AbstractPhysics.linear_base`:
    the base of physics + effects, the physics under a learned force), by the exact path, driven by the same
    input; ``None`` where there is no linear base or the grid is not uniform.

    Effects and learned forces are usually corrections to the base, so its trajectory starts Newton near
    the solution: a weak effect then converges in about half the sweeps of a start from $x_0$ held.
    """
    base = physics.linear_base()
    h = None if base is None else exact_step(base, t)
    if h is None:
        return None
    with torch.no_grad():
        A, B, _, _ = base.state_space()
        return simulate_lti_states(A, B, h, u, x0, hold)


def _completed(guess: torch.Tensor, x0: torch.Tensor) -> torch.Tensor:
    """``guess`` (batch, time, k) with the states after its k held at ``x0`` (batch, n): the base's states of
    ``physics + effect``, the effects' own states added."""
    if guess.shape[-1] == x0.shape[-1]:
        return guess
    held = x0[:, None, guess.shape[-1]:].expand(-1, guess.shape[1], -1)
    return torch.cat([guess, held.to(guess)], dim=-1)


def base_guess(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor,
               hold: str = "foh") -> torch.Tensor | None:
    """Newton's start without a warm one: :func:`linear_guess` from ``x0`` (batch, n), the states of effects that
    the linear base does not have held at ``x0``; ``None`` without a linear base or a uniform grid."""
    guess = linear_guess(physics, t, u, x0[..., :_linear_states(physics, x0.shape[-1])], hold)
    return None if guess is None else _completed(guess, x0)


def _linear_states(physics: Dynamics, n: int) -> int:
    """How many of the ``n`` states the linear base has (:func:`linear_guess`): all, unless effects add their own."""
    base = physics.linear_base()
    return n if base is None else base.state_dim


class _NotConverged(Exception):
    """Newton did not converge within its sweeps: :func:`solve_shooting` retries with longer segments, from the
    last sweep's states (``args[0]``, (batch, time, n)), whose settled prefix is exact."""


class ShootingSolution:
    """A converged multiple-shooting solution: the layout, the starts, T, and the states of the last sweep."""

    def __init__(self, layout: _Layout, states: torch.Tensor, T: torch.Tensor | None, starts: torch.Tensor | None):
        self.layout, self.centre, self.T, self.starts = layout, states, T, starts

    @property
    def trajectory(self) -> torch.Tensor:
        """The converged states (batch, N, n), without gradients: a warm start for a nearby solve."""
        return self.layout.assemble(self.centre.detach())

    def states(self, physics: Dynamics, x0: torch.Tensor) -> torch.Tensor:
        r"""The record's states (batch, N, n), differentiable through the implicit-function correction.

        One sweep from the converged starts gives $x_{s,k}(\theta)$; the scan of the continuity defects
        gives the starts' drift, and $x + T\,\delta\xi$ carries both (module docstring). Reverse mode
        (backward), forward mode (``torch.func.jvp``) and central differences all go through it.
        """
        if self.T is None:
            return self.layout.assemble(self.centre)
        with parametrize.cached():
            states = self.layout.sweep(physics, self.starts[None])[0]
        defects = states[:, :-1, -1] - self.starts[:, 1:]
        drift = linear_recurrence(self.T[:, :-1, -1], defects, x0 - self.starts[:, 0])
        return self.layout.assemble(states + (self.T @ drift[:, :, None, :, None])[..., 0])


def solve_shooting(
    physics: Dynamics,
    t: torch.Tensor,
    u: torch.Tensor,
    x0: torch.Tensor,
    solver: Method,
    *,
    tol: float | None = None,
    max_sweeps: int = 16,
    sensitivities: bool = True,
    guess: torch.Tensor | None = None,
    warm: WarmStart | None = None,
    hold: str = "foh",
) -> ShootingSolution:
    """Run Newton to convergence (arguments of :func:`simulate_shooting`), without recording gradients.

    With ``sensitivities`` the last sweep is graded (central differences, T exact to ~1e-10); without, its
    T comes from forward differences. Either way the last update is applied linearly (:func:`_newton`).
    ``guess``: the states (batch, time, n) of a nearby solution (the previous iterate of a fit), or of its first
    states (those of the base of ``physics + effect``, the effects' own states then held at ``x0``), whose
    values at the segment starts start Newton. Without it, Newton starts from the linear base's exact
    trajectory (:func:`linear_guess`) where there is one, else from $x_0$ held.
    ``warm``: the record's :class:`~torchpaml._simulate.warm.WarmStart`; its ``states``, when set, are the
    guess, and this solution's trajectory replaces them.
    ``hold``: ``"foh"`` or ``"zoh"`` (module docstring).
    """
    check_hold(hold)
    if solver.substeps == "auto":
        raise ConfigurationError(f"the shooting engine needs a fixed-step method at a whole number of substeps, got "
                                 f"{solver!r}")
    tol = tol if tol is not None else GRADIENT_TOL if sensitivities else NEWTON_TOL
    if warm is not None and not isinstance(warm, WarmStart):
        raise ConfigurationError(f"warm must be a torchpaml.WarmStart kept per record (warm=tp.WarmStart()), got "
                        f"{type(warm).__name__}")
    exact = compiled_states(physics, t, u, x0, solver, hold)
    if exact is not None:
        guess = exact
    elif warm is not None and warm.states is not None:
        guess = warm.states
    guess = base_guess(physics, t, u, x0, hold) if guess is None else _completed(guess, x0)
    length = solver.segment
    while True:
        layout = _Layout(t, u, solver, length, hold)
        try:
            with torch.no_grad():
                states, T, starts = _newton(physics, layout, x0.detach(), tol, max_sweeps, sensitivities,
                                            guess, settled=exact is not None)
            # constants of the solution: no_grad stops reverse mode, detach also stops forward mode's tangents
            solution = ShootingSolution(layout, states.detach(), T, None if starts is None else starts.detach())
            if warm is not None:
                warm.states = solution.trajectory
            return solution
        except _NotConverged as last:
            guess = last.args[0] if bool(torch.isfinite(last.args[0]).all()) else guess
            exact = None
            length = layout.L * GROWTH  # fewer, longer segments; one is plain sequential stepping, which always ends


def simulate_shooting(physics: Dynamics, t: torch.Tensor, u: torch.Tensor, x0: torch.Tensor, solver: Method,
                      warm: WarmStart | None = None, **options) -> torch.Tensor:
    r"""States of ``physics`` on the sample grid by ``solver`` (RK4 or TRBDF2 at fixed substeps), parallel in
    time (module docstring).

    Args:
        physics: an :class:`~torchpaml.AbstractPhysics`; ``derivative(t, x, u)`` is called with
            t of shape (rows,), x (rows, n_state), u (rows, n_input).
        t: sample times, (time,), strictly increasing (uniform or not).
        u: input samples, (batch, time, n_input).
        x0: initial state, (batch, n_state).
        solver: a :class:`~torchpaml._simulate.solvers.FixedStep` with whole ``substeps``; its ``segment`` is
            the steps per shooting segment L.
        warm: a :class:`~torchpaml._simulate.warm.WarmStart` the caller keeps between solves of the same record
            under nearby parameters (the steps of a training run): the converged states are stored in it and
            start the next solve's Newton, which then needs fewer sweeps.
        options: ``tol`` (Newton stops when every continuity defect is below ``tol`` times the state's scale;
            default :data:`NEWTON_TOL`, or :data:`GRADIENT_TOL` when grad mode is on), ``max_sweeps`` (sweeps
            before Newton gives up and the segments are made :data:`GROWTH` times longer, for chaotic or very
            stiff records; in the limit one segment, plain sequential stepping), ``hold`` (``"foh"``, the input
            linear between samples, or ``"zoh"``, held constant).

    Returns:
        states: (batch, time, n_state), differentiable in the parameters, ``u`` and ``x0`` (reverse and
        forward mode) when grad mode is on: by the compiled sensitivities where the physics compiles
        (:mod:`~torchpaml._simulate.compiled_gradient`), else by this engine; a differentiated backward
        (``create_graph=True``) by reverse mode through every step (:mod:`~torchpaml._simulate.second_order`).
    """
    if len(t) < 2:
        return x0[:, None]
    if warm is not None and not isinstance(warm, WarmStart):
        raise ConfigurationError(f"warm must be a torchpaml.WarmStart kept per record (warm=tp.WarmStart()), got "
                                 f"{type(warm).__name__}")
    hold = options.get("hold", "foh")
    states = compiled_gradient_states(physics, t, u, x0, solver, hold)
    if states is None:
        solution = solve_shooting(physics, t, u, x0, solver, sensitivities=torch.is_grad_enabled(), warm=warm, **options)
        states = solution.states(physics, x0)
    elif warm is not None:
        warm.states = states.detach()
    if not torch.is_grad_enabled():
        return states
    inputs = [v for v in (t, u, x0, *physics.parameters(), *constants(physics)) if v.requires_grad]
    return with_second_order(states, lambda: one_segment(physics, _Layout(t, u, solver, len(t), hold), x0), inputs)
