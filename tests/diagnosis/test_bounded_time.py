"""Every diagnosis in bounded time: refit only what can pass the rule, each refit within its budget, and say why.

The records are simulated here: a pendulum with cubic damping (a force outside the library) diagnosed with the
discovery, and the hidden-effect oscillator with Coulomb friction, whose second rung scores the effects with memory.
Their times are in ``benchmarks/bench_worst_case.py``; these tests check the answers and the explanations.
"""

import json
import logging

import pytest
import torch

from experiment_modules import load

from torchpaml import (
    ConfigurationError,
    CoulombFriction,
    Discoverer,
    DynamicFriction,
    Pendulum,
    Ranker,
    Simulated,
    build_model,
    default_effects,
    diagnose,
    write_report,
)
from torchpaml.analysis import model_ladder
from torchpaml.report import discovery_to_dict, ranking_table

pytestmark = pytest.mark.slow  # an end-to-end run: the slow lane

forces = load("discovery/forces.py")

REASONS = ("refitted: ", "not refitted: ", "undecided: ")
MEMORY = {"hysteresis", "dynamic_friction", "input_lag"}


def records(system, samples, dt=0.05, noise=0.02):
    duration = (samples - 1) * dt
    return (Simulated(system, "pseudorandom", 1.0, [0], duration, dt, noise=noise).experiments(),
            Simulated(system, "multisine", 1.0, [1], duration, dt, noise=noise).experiments())


def every_candidate_says_why(diagnosis):
    for ranking in diagnosis.ladder.rankings:
        table = ranking_table(ranking)
        for entry in ranking.entries:
            assert entry.refit_reason.startswith(REASONS), (entry.effect, entry.refit_reason)
            assert entry.refit_reason in table
            assert (entry.refit is not None or entry.failure is not None) == entry.refit_reason.startswith("refitted")


def test_a_pendulum_with_a_force_outside_the_library_is_diagnosed_and_its_form_discovered():
    truth = Pendulum(zeta=0.2, omega0=2.0, gain=2.0, learn=()) + forces.CubicDamping(0.5)
    train, validation = records(truth, 4001)
    diagnosis = diagnose(Pendulum(zeta=0.4, omega0=1.6, gain=1.5, learn=("zeta", "omega0", "gain")),
                         default_effects(), train, validation, discovery=Discoverer())
    every_candidate_says_why(diagnosis)
    found = discovery_to_dict(diagnosis.discovery)
    final = found["nrmse_validation"]["discovered"]
    assert final < 1.2 * 0.02, diagnosis.verdict  # at the noise floor: by library effects, the discovery, or both
    if found["recommended"]:  # what the discovery adds is the truth's form
        terms = {t["term"]: t["coefficient"] for t in found["terms"]}
        assert terms.get("v**3") == pytest.approx(-0.5, rel=0.1), terms
    # the second rung's effects with memory cannot pass the rule at their first-order scores: not refitted
    second = diagnosis.ladder.rankings[1]
    assert all(e.refit_reason.startswith("not refitted") for e in second.entries if e.effect in MEMORY), \
        ranking_table(second)


def test_the_second_rung_of_an_oscillator_with_coulomb_friction_scores_the_effects_with_memory():
    device = build_model("oscillator", {"zeta": 0.2, "gain": 4.0}, {"coulomb_friction": 0.5})
    train, validation = records(device, 2001)
    diagnosis = diagnose(build_model("oscillator").set_learnable("zeta", "omega0", "gain"), default_effects(), train,
                         validation)
    assert diagnosis.ladder.added == ["coulomb_friction"], diagnosis.verdict
    assert diagnosis.ladder.final.nrmse_validation < 1.2 * 0.02
    every_candidate_says_why(diagnosis)
    second = diagnosis.ladder.rankings[1]
    assert MEMORY <= {e.effect for e in second.entries if e.score > 0}  # scored, each from its own states
    assert not second.undecided


def test_a_tiny_refit_budget_leaves_candidates_undecided_and_the_verdict_and_the_files_say_so(tmp_path):
    torch.manual_seed(0)
    device = build_model("oscillator", {"zeta": 0.2, "gain": 4.0}, {"coulomb_friction": 0.5})
    train, validation = records(device, 601)
    physics = build_model("oscillator").set_learnable("zeta", "omega0", "gain")
    diagnosis = diagnose(physics, default_effects(), train, validation, ranker=Ranker(refit_budget=1e-9))
    undecided = diagnosis.ranking.undecided
    assert [e.effect for e in undecided] == ["coulomb_friction", "quadratic_damping"], ranking_table(diagnosis.ranking)
    assert all(e.refit_reason.startswith("undecided: over budget (") for e in undecided)
    assert diagnosis.ladder.added == []  # nothing decided, nothing added
    assert "Undecided (their refits stopped over budget): coulomb_friction on Oscillator" in diagnosis.verdict
    assert "--refit_budget" in diagnosis.verdict and "--budget" in diagnosis.verdict
    write_report(diagnosis, tmp_path)
    content = json.loads((tmp_path / "diagnosis.json").read_text())
    assert [u["effect"] for u in content["undecided"]] == ["coulomb_friction", "quadratic_damping"]
    rows = {row["effect"]: row for row in content["ranking"]}
    assert rows["coulomb_friction"]["undecided"] > 0 and not rows["coulomb_friction"]["refitted"]
    assert "Undecided" in (tmp_path / "report.html").read_text()


def test_a_whole_budget_too_short_for_the_physics_fit_is_refused_in_one_line_that_names_it():
    device = build_model("oscillator", {"zeta": 0.2, "gain": 4.0}, {"coulomb_friction": 0.5})
    train, validation = records(device, 601)
    physics = build_model("oscillator").set_learnable("zeta", "omega0", "gain")
    with pytest.raises(ConfigurationError, match=r"fitting Oscillator did not end within the diagnosis' budget .*"
                                                 r"--budget"):
        diagnose(physics, default_effects(), train, validation, budget=1e-6)

def lugre_records(samples=601):
    """An oscillator with LuGre friction of a sharp sign (its Coulomb deflection, 1e-3, about the largest change of
    the position over one sample): the effect with memory that the second rung's fit starts from."""
    device = build_model("oscillator", {"zeta": 0.2, "gain": 4.0}) + DynamicFriction(sigma0=400.0, zc=1e-3)
    return records(device, samples)


def test_a_rung_after_an_effect_with_memory_under_a_sharp_sign_keeps_its_bound_and_ends_its_fit(caplog):
    """From the refit's optimum the rung's fit would drift towards the sharp truth (zc 1e-3), each evaluation costlier
    as the sign sharpens: unbounded, at 1 201 samples, 86.6 s, 71 times its refit. The effect's bound (zc at least
    half the largest change of y over one sample, :meth:`~torchpaml.DynamicFriction.bounds`) holds in the rung's fit
    as in the refit, so the fit ends, within its budget, on the bound."""
    train, validation = lugre_records()
    physics = build_model("oscillator").set_learnable("zeta", "omega0", "gain")
    with caplog.at_level(logging.INFO, logger="torchpaml"):
        ladder = model_ladder(physics, [DynamicFriction()], train, validation)
    assert ladder.added == ["dynamic_friction"], ranking_table(ladder.rankings[0])
    assert ladder.rankings[1].fit_over_budget is None
    bound = DynamicFriction().bounds(train)["zc"][0]
    assert ladder.final.parameters["dynamic_friction.zc"] >= bound * (1 - 1e-9)
    assert ladder.final.parameters["dynamic_friction.zc"] > 10 * 1e-3  # the truth lies beyond what the samples resolve
    lines = [r.getMessage() for r in caplog.records]
    assert "fitting Oscillator + dynamic_friction on 600 samples" in lines
    assert any(line.startswith("refitting Oscillator + dynamic_friction (at most ") for line in lines), lines
    assert not any("stopped over its budget" in line for line in lines)


def test_a_tiny_budget_on_a_rung_fit_keeps_its_refits_parameters_and_the_verdict_and_the_files_say_so(tmp_path):
    device = build_model("oscillator", {"zeta": 0.2, "gain": 4.0}, {"coulomb_friction": 0.5})
    train, validation = records(device, 601)
    physics = build_model("oscillator").set_learnable("zeta", "omega0", "gain")
    diagnosis = diagnose(physics, [CoulombFriction()], train, validation, ranker=Ranker(fit_budget=1e-9))
    assert diagnosis.ladder.added == ["coulomb_friction"]
    stopped = diagnosis.ladder.rankings[1]
    assert stopped.fit_over_budget is not None
    assert diagnosis.ladder.final.parameters == diagnosis.ranking.recommended.refit.parameters  # the refit's
    assert ("Over budget, these rungs keep the parameters of the refit that found their effect" in diagnosis.verdict
            and "Oscillator + coulomb_friction (its fit stopped after" in diagnosis.verdict
            and "--fit_budget" in diagnosis.verdict), diagnosis.verdict
    write_report(diagnosis, tmp_path)
    rungs = json.loads((tmp_path / "diagnosis.json").read_text())["ladder"]
    assert rungs[0]["fit_over_budget"] is None and rungs[1]["fit_over_budget"] == stopped.fit_over_budget
