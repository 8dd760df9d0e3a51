"""A physics holds parameters and equations only: a fit writes the fitted values and nothing else onto it."""

import copy

import torch

from torchpaml import CubicStiffness, Record, Oscillator, fit_physics, pseudorandom, simulate, time_grid


def _attributes(module: torch.nn.Module) -> dict[str, dict[str, int]]:
    """Every submodule's plain attributes (not its parameters or buffers), by name, each as the id of its value."""
    return {name: {key: id(value) for key, value in vars(sub).items() if not key.startswith("_parameters")}
            for name, sub in module.named_modules()}


def _record() -> Record:
    t = time_grid(20.0, 0.05)
    u = pseudorandom(t, 1.0, seed=3)
    y = simulate(Oscillator(zeta=0.2, omega0=2.0, gain=4.0) + CubicStiffness(1.5), t, u).detach()
    return Record.records(t, u, y)[0]


def test_calling_the_model_means_the_same_before_and_after_a_fit_of_a_copy():
    record = _record()
    t, u = record.t, record.u[None]
    model = Oscillator(zeta=0.3, omega0=2.0, gain=4.0) + CubicStiffness(1.0)
    fitted = copy.deepcopy(model)
    with torch.no_grad():
        before = model(t, u)
        fit = fit_physics(fitted, record)
        fitted.load_state_dict(model.state_dict())  # the copy back at the start: only the values differed
        after = fitted(t, u)
        default = simulate(model, t, u)
    assert fit.solver.substeps >= 1
    assert torch.equal(before, after)
    assert torch.equal(before, default)  # calling it is simulate by the default solver


def test_no_fit_writes_an_attribute_onto_the_module_it_is_given():
    model = Oscillator(zeta=0.3, omega0=2.0, gain=4.0) + CubicStiffness(1.0)
    attributes, keys = _attributes(model), set(model.state_dict())
    fit = fit_physics(model, _record())
    assert _attributes(model) == attributes
    assert set(model.state_dict()) == keys
    assert not hasattr(model, "solver") and "± std" not in model.describe()
    assert "± std" in model.describe(fit.uncertainty)
