"""The diagnosis' stages are frozen values: the ranker, the initial-state policy and the discoverer."""

import dataclasses

import pytest

from torchpaml import (
    ConfigurationError,
    Discoverer,
    Estimate,
    Ranker,
    Rest,
    SelectionRule,
    TermLibrary,
    fit_physics,
)
from torchpaml._diagnostics.diagnosis import _stages
from torchpaml._fit.initial_state import as_initial_state


def test_the_stages_are_frozen_values_that_compare_and_refuse_bad_settings():
    assert Ranker(shortlist=3) == Ranker(shortlist=3) != Ranker()
    with pytest.raises(dataclasses.FrozenInstanceError):
        Ranker().shortlist = 4
    with pytest.raises(ConfigurationError, match="shortlist must be at least 1"):
        Ranker(shortlist=0)
    with pytest.raises(ConfigurationError, match="refit_budget must be positive"):
        Ranker(refit_budget=0.0)
    with pytest.raises(ConfigurationError, match="max_iter must be a whole number"):
        Discoverer(max_iter=0)


def test_the_initial_state_policies_and_their_names():
    with pytest.warns(DeprecationWarning):
        assert as_initial_state("rest") == Rest() and as_initial_state("estimate") == Estimate()
    assert as_initial_state(Estimate()) is not None and Estimate().estimated and not Rest().estimated
    with pytest.raises(ConfigurationError, match=r"initial_state must be Rest\(\) or Estimate\(\)"):
        as_initial_state("guess")


def test_the_earlier_keywords_still_work_with_a_warning_naming_the_stage_that_replaces_them():
    with pytest.warns(DeprecationWarning, match=r"ranker=Ranker\(\.\.\.\)"):
        ranker, discovery = _stages(None, None, {"shortlist": 3, "rule": SelectionRule("aic"), "discover": True,
                                                 "terms": ["x**2*v"]})
    assert ranker == Ranker(rule=SelectionRule("aic"), shortlist=3)
    assert discovery == Discoverer(library=TermLibrary(terms=("x**2*v",)))
    assert _stages(None, None, {}) == (Ranker(), None)
    with pytest.raises(ConfigurationError, match="unexpected keyword"):
        _stages(None, None, {"shortlsit": 3})
    with pytest.raises(ConfigurationError, match="give the ranking's settings once"):
        with pytest.warns(DeprecationWarning):
            _stages(Ranker(), None, {"shortlist": 3})


def test_a_policy_object_and_its_name_fit_alike(grid):
    import torch

    from torchpaml import Record, Oscillator, pseudorandom, simulate

    u = pseudorandom(grid, 1.0, seed=2)
    y = simulate(Oscillator(zeta=0.3, omega0=2.0), grid, u, torch.tensor([[0.4, -0.2]])).detach()
    record = Record(grid, u[0], y[0])
    with pytest.warns(DeprecationWarning, match=r"initial_state='estimate' is deprecated: pass Estimate\(\)"):
        by_name = fit_physics(Oscillator(zeta=0.5, omega0=2.0), record, initial_state="estimate")
    by_policy = fit_physics(Oscillator(zeta=0.5, omega0=2.0), record, initial_state=Estimate())
    assert by_name.parameters == by_policy.parameters
    assert torch.equal(by_name.initial_states[0], by_policy.initial_states[0])
    assert by_policy.initial_states[0].tolist() == pytest.approx([0.4, -0.2], abs=1e-6)
