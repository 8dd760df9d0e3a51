"""The compiled outputs and Jacobians (torchpaml._simulate.compiled_jacobian) against the torch engine.

The oracle is reverse mode through the engine's own sweep (RK4's stages, TR-BDF2's Newton stages with their
implicit-function correction) over one segment: the exact derivative of the same discrete map, projected on random
cotangents $w$ ($w^T J$, one backward pass each: a wrong entry of J moves every projection). Tolerances:
- RK4: the same stages in the same order, the rates printed from the closed form: 1e-9 relative to each column's
  largest entry (measured 4e-15);
- TR-BDF2: each stage's Newton stops at 1e-12 of the state's scale, in torch and in C from different iterates:
  1e-9 (measured 3e-12);
- the engine's own Jacobian, central differences of its sweeps, has an error of ~1e-7 relative on these records:
  the compiled one replaces it, and is checked against the oracle, not against it.
"""

import pytest
import torch

from tests.two_mass import TwoMass
from torchpaml import (RK4, TRBDF2, CoulombFriction, CubicStiffness, Estimate, Hysteresis, InputLag, Oscillator,
                       Record)
from torchpaml._fit.trust_region import TrustRegionProblem
from torchpaml._simulate import compiled_jacobian as jacobians
from torchpaml._simulate.sensitivity import raw_parameters, shooting_jacobian
from torchpaml._simulate.shooting import _Layout
from torchpaml._simulate.warm import WarmStart
from torchpaml._symbolic.compiler import compiler

pytestmark = pytest.mark.skipif(compiler() is None, reason="the compiled Jacobian needs a C compiler on PATH")

TOLERANCE = 1e-9


def _physics(case: str):
    base = Oscillator(zeta=0.1, omega0=1.0, gain=1.0, learn=("zeta", "omega0", "gain"))
    return {"hardening spring": base + CubicStiffness(200.0),
            "smoothed friction": base + CoulombFriction(0.02),
            "hysteresis": base + Hysteresis(),
            "input lag": base + InputLag(0.3),
            "two outputs": TwoMass()}[case]


def _drive(physics, samples: int = 200, seed: int = 0):
    generator = torch.Generator().manual_seed(seed)
    t = torch.arange(samples, dtype=torch.float64) * 0.05
    u = 0.2 * torch.randn(1, samples, physics.input_dim, generator=generator, dtype=torch.float64)
    x0 = physics.initial_state(1)
    x0[0, :2] = torch.tensor([0.05, -0.02], dtype=torch.float64)
    return t, u, x0


#: Random cotangents per check: each is one backward pass; a wrong entry of J moves every projection.
PROJECTIONS = 4


def _projections(shape: tuple, seed: int = 7) -> torch.Tensor:
    """(PROJECTIONS, *shape) random cotangents."""
    return torch.randn(PROJECTIONS, *shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)


def _oracle(physics, raw: dict, t, u, x0, solver, hold: str, cotangents: torch.Tensor) -> torch.Tensor:
    """$w^T J$ for each cotangent $w$ (time, n_output) by reverse mode through the engine's sweep over one segment:
    (PROJECTIONS, p + n_state)."""
    method = solver.at(solver.resolution)
    layout = _Layout(t, u, method, len(t) - 1, hold)
    start = x0.clone().requires_grad_(True)
    states = method.sweep(physics, start, layout.stages(1))  # (n, L + 1, rows)
    y = physics.output(states[:, :, 0].t()[None], u)[0]  # (time, n_output)
    leaves = list(raw.values()) + [start]
    rows = []
    for w in cotangents:
        grads = torch.autograd.grad((y * w).sum(), leaves, retain_graph=True, allow_unused=True)
        rows.append(torch.cat([torch.zeros(1, dtype=torch.float64) if g is None else g.reshape(-1) for g in grads]))
    return torch.stack(rows)


def _projected(J: torch.Tensor, cotangents: torch.Tensor) -> torch.Tensor:
    """$w^T J$ of the compiled J (time, n_output, columns): (PROJECTIONS, columns)."""
    return torch.einsum("kto,toc->kc", cotangents, J)


def _relative_columns(a: torch.Tensor, b: torch.Tensor) -> float:
    """The largest error of a column of ``a`` relative to the largest entry of ``b``'s column."""
    a, b = a.reshape(-1, a.shape[-1]), b.reshape(-1, b.shape[-1])
    return float(((a - b).abs().amax(dim=0) / b.abs().amax(dim=0).clamp(min=1e-300)).max())


CASES = [(case, "foh") for case in ("hardening spring", "smoothed friction", "hysteresis", "input lag", "two outputs")]


@pytest.mark.parametrize("case,hold", CASES + [("input lag", "zoh")], ids=[f"{c}-{h}" for c, h in CASES] + ["input lag-zoh"])
@pytest.mark.parametrize("solver", [RK4(substeps=2), TRBDF2(substeps=1)], ids=["RK4", "TRBDF2"])
def test_the_compiled_jacobian_is_the_engines_exact_derivative(case, hold, solver):
    physics = _physics(case)
    t, u, x0 = _drive(physics)
    raw = raw_parameters(physics, physics.learnable_names())
    compiled = jacobians.compiled_jacobian(physics, raw, t, u, x0, solver, hold, True, kinks=True)
    assert compiled is not None
    y, J = compiled
    cotangents = _projections(J.shape[1:3])
    oracle = _oracle(physics, raw, t, u, x0, solver, hold, cotangents)
    with torch.no_grad():
        engine_y = physics.output(solver.states(physics, t, u, x0, hold=hold), u)
    assert float((y - engine_y).abs().max() / engine_y.abs().max()) < TOLERANCE
    assert J.shape == (1, len(t), physics.output_dim, len(raw) + physics.state_dim)
    assert _relative_columns(_projected(J[0], cotangents), oracle) < TOLERANCE


def test_records_of_unequal_length_with_their_initial_states_stack_in_their_blocks(monkeypatch):
    physics = _physics("hardening spring")
    records = []
    for samples, seed in ((150, 1), (230, 2)):
        t, u, x0 = _drive(physics, samples, seed)
        records.append(Record(t, u[0], torch.sin(t)[:, None]))
    names = physics.learnable_names()
    problem = TrustRegionProblem(physics, records, names, Estimate(), RK4(substeps=1), [WarmStart(), WarmStart()],
                                 None)
    x = problem.start(None, *[torch.full((len(names) + 4,), v, dtype=torch.float64).numpy() for v in (-1e9, 1e9)])
    x[len(names):] = [0.05, -0.02, -0.03, 0.01]
    residual, J = problem.evaluate(x)
    raw = raw_parameters(physics, names)
    scale = problem.scale.numpy()
    rows = 0
    for i, (record, x0) in enumerate(zip(records, problem.starts(x), strict=True)):
        cotangents = _projections((len(record.t), 1))
        oracle = _oracle(physics, raw, record.elapsed, record.u[None], x0, RK4(substeps=1), record.hold, cotangents)
        block = torch.from_numpy(J[rows:rows + len(record.t)] * -scale[rows:rows + len(record.t), None])
        own = torch.cat([block[:, :len(names)], block[:, len(names) + 2 * i:len(names) + 2 * i + 2]], dim=1)
        assert _relative_columns(_projected(own[:, None], cotangents), oracle) < TOLERANCE
        assert (block[:, len(names) + 2 * (1 - i):len(names) + 2 * (1 - i) + 2] == 0).all()
        rows += len(record.t)
    assert rows == len(residual)


#: A kinked physics' Jacobian in C against the engine's: both central differences of the same step, of whole compiled
#: simulations and of the engine's sweeps from its converged starts; they differ by rounding over the step and by
#: TR-BDF2's Newton stops (measured on this record: 4.5e-10 for RK4, 1.6e-9 for TR-BDF2).
DIFFERENCED = 1e-8


@pytest.mark.parametrize("solver", [RK4(substeps=1), TRBDF2(substeps=1)], ids=["RK4", "TRBDF2"])
def test_a_physics_with_a_kink_is_differentiated_across_it_in_c(solver):
    """Hysteresis has |v| and |z|: its exact slope flips at once where they cross zero, so a fit takes central
    differences that see the kink across their step, of whole simulations in C (the exact one-sided slopes above
    are still there, on demand)."""
    physics = _physics("hysteresis")
    t, u, x0 = _drive(physics)
    raw = raw_parameters(physics, physics.learnable_names())
    y, J = jacobians.compiled_jacobian(physics, raw, t, u, x0, solver, "foh", True)
    engine_y, engine_J = shooting_jacobian(physics, raw, t, u, x0, solver, None, True, "foh")
    exact = jacobians.compiled_jacobian(physics, raw, t, u, x0, solver, "foh", True, kinks=True)[1]
    assert float((y - engine_y).abs().max() / engine_y.abs().max()) < TOLERANCE
    error = _relative_columns(J, engine_J)
    assert error < DIFFERENCED, f"{error:.2e}"
    assert J.shape == exact.shape == engine_J.shape


def test_a_difference_whose_side_blows_up_takes_the_other_side():
    """A kinked physics' Jacobian is central differences of whole simulations: where one side's simulation blows up
    past the engine's bound while the output stays finite (the cascaded tanks at RK4's edge of stability gave a side
    of ~1e250 and a central column of 6e256, whose square overflowed the trust region's scaling into NaN unknowns),
    the column is the other side's one-sided difference; where both sides blow up, or the output itself, the point
    is refused as the engine refuses a blow-up."""
    import numpy as np

    from torchpaml import SimulationError

    t, u, x0 = torch.arange(5.0), torch.zeros(1, 5, 1), torch.zeros(1, 1)

    def simulate(parameters, columns, t, u, x0):  # y = p up to 1, a blow-up beyond, except at exactly p = 3
        p = float(parameters[0])
        y = torch.full((1, len(t), 1), p, dtype=torch.float64)
        return (1e250 * y if p > 1.0 and p != 3.0 else y), None

    y, J = jacobians._differenced(simulate, np.array([0.5]), [0], t, u, x0)  # both sides tame: the central slope
    assert float(J.max()) == pytest.approx(1.0, rel=1e-6) and float(y.max()) == 0.5
    y, J = jacobians._differenced(simulate, np.array([1.0]), [0], t, u, x0)  # the upper side past 1e8: the lower's
    assert float(J.max()) == pytest.approx(1.0, rel=1e-6) and float(J.min()) == float(J.max())
    with pytest.raises(SimulationError, match="both sides"):
        jacobians._differenced(simulate, np.array([3.0]), [0], t, u, x0)
    with pytest.raises(SimulationError, match="simulated output blew up"):
        jacobians._differenced(simulate, np.array([2.0]), [0], t, u, x0)  # the output itself, as the engine says


def test_a_side_whose_newton_fails_takes_the_other_side():
    """A side's simulation that fails (its TR-BDF2 Newton, a :class:`~torchpaml.SimulationError`) is a side that
    blew up: the column is the other side's one-sided difference."""
    import numpy as np

    from torchpaml import SimulationError

    t, u, x0 = torch.arange(5.0), torch.zeros(1, 5, 1), torch.zeros(1, 1)

    def simulate(parameters, columns, t, u, x0):  # y = 2p below 1; Newton fails beyond
        p = float(parameters[0])
        if p > 1.0:
            raise SimulationError("TR-BDF2's Newton did not converge in the step from t = 2 s")
        return torch.full((1, len(t), 1), 2 * p, dtype=torch.float64), None

    y, J = jacobians._differenced(simulate, np.array([1.0]), [0], t, u, x0)
    assert float(J.max()) == pytest.approx(2.0, rel=1e-6) and float(J.min()) == float(J.max())


def test_a_stage_whose_newton_fails_is_a_refused_point_as_in_the_engine():
    """A friction sign sharper than TR-BDF2's step can resolve (width 1e-5 at 0.5 s per step): no stage solution
    exists where the friction's jump exceeds the step's reach, so the Newton cycles. The compiled Jacobian raises
    (a fit rejects the point), as the engine does, and never hands the point to the engine's slower Newton."""
    from torchpaml import SimulationError

    physics = Oscillator(zeta=0.1, omega0=1.0, gain=1.0, learn=("zeta",)) + CoulombFriction(5.0, eps=1e-5)
    t = torch.arange(50, dtype=torch.float64) * 0.5
    u, x0 = 8 * torch.sin(t)[None, :, None], physics.initial_state(1)
    raw = raw_parameters(physics, physics.learnable_names())
    with pytest.raises(SimulationError, match="Newton did not converge in the step from t = "):
        jacobians.compiled_jacobian(physics, raw, t, u, x0, TRBDF2(substeps=1), "foh", False)
    with pytest.raises(SimulationError, match="Newton did not converge"):
        shooting_jacobian(physics, raw, t, u, x0, TRBDF2(substeps=1), None, False, "foh")
    assert jacobians.implicit_states(physics, t, u, x0, TRBDF2(substeps=1), "foh") is None  # simulate: the engine's
