r"""Cascaded tanks (measured): diagnose a user's linear two-tank physics with user-written effects.

    python experiments/cascaded_tanks/run.py --out DIR [--data PATH] [--discover]

The protocol is the registered :data:`BENCHMARK` (:mod:`torchpaml.leaderboard`; the data:
``shared/data/cascaded_tanks/README.md``): ``estimation`` for training (its last quarter held out inside it for
validation), ``test`` for the test only. Both records
start from the same unknown state, so the initial state is estimated with the parameters on the
training part (which starts where ``estimation`` starts) and the test is simulated from it: no test
sample is used, not even the loader's 5-sample initialisation window.

1. The physics: :class:`tanks.TwoTanks`, linear outflows. With only the lower level measured, the
   upper level's scale is free: k2 and k4 enter the output only as their product (the fit's
   identifiability warning says so), so k2 is fixed and k1, k3, k4 are learned.
2. :func:`~torchpaml._diagnostics.diagnose` with ``initial_state=Estimate()`` and the candidates
   ``sqrt_outflow_upper``, ``sqrt_outflow_lower`` (Torricelli), ``upper_overflow`` (the upper tank
   spills above a rim), ``lower_overflow`` (the lower tank spills above a level) and ``sensor_clip`` (the level reads
   clipped at 10 V), plus the library's ``output_saturation`` and ``dead_zone``, which apply to any physics. The
   greedy path takes ``lower_overflow`` on its second rung, before the upper tank's overflow, and ends worse on
   validation; the ladder's beam (three models per rung) climbs the runner-up's path too, and validation chooses.
3. Every rung, the hybrid and every probe's extension are scored on ``test``.
4. With ``--discover``, the discovery alone on the linear ``TwoTanks`` (no user effects): which rates
   the physics misses, in closed form (:func:`~torchpaml._diagnostics.discover_missing_force`), scored
   on ``test`` as ``discovery {expression, terms, rmse {test}}``.

5. The final model refitted with the spill rate free (:func:`free_spill`), unless ``--free-spill`` ran the whole
   diagnosis so: ``free_spill {rate, solver, rmse {test}, seconds}`` (``null`` then, or where no overflow was found).
6. Hypotheses tried beside the diagnosis, not kept (``tried``; :func:`hypotheses`): the sensor's zero off the outlet
   (``sensor_offset``) on the final model, scored on validation, and the final model refitted on the whole
   estimation record.

Writes ``DIR/cascaded_tanks.json`` in the shape of ``silverbox.json``, with ``rmse: {"test": V,
"test_official_window": V}`` (ours, then the official scoring of :data:`OFFICIAL`) and
``nrmse: {"test": RMSE / std y}``, plus the leaderboard's fields (:mod:`torchpaml.leaderboard`; ``goal`` with what
limits the figure: the registry's rule, :func:`~torchpaml.leaderboard.diagnosed_goal`, with :func:`measured`'s
figures), and the diagnosis folder ``DIR/diagnosis/``.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import time
from pathlib import Path

from tanks import (FREE_SPILL_RATE, MAX_SPILL_RATE, LowerOverflow, SensorClip, SensorOffset, TorricelliOutflow,
                   TwoTanks, UpperOverflow)

from torchpaml import (Budget, DeadZone, Diagnosis, Discoverer, Estimate, ModelScore, OutputSaturation, Record,
                       diagnose, fit_physics, simulate_record, write_report)
from torchpaml.cli.progress import progress_lines
from torchpaml.leaderboard import (SCHEMA_VERSION, agreement_evidence, benchmark, diagnosed_goal, hybrid_entry,
                                   hypothesis_entry, ladder_entries, tried_entries, validation_agreement, with_effect,
                                   write_result)
from torchpaml.report import diagnosis_to_dict, discovery_to_dict, ranking_table

BENCHMARK = benchmark("cascaded_tanks")
#: The official scoring of ``nonlinear_benchmarks`` (1.0 and later), beside ours: the first 50 test samples set the
#: state (estimated on them), the RMSE counts from sample 50 on; each rung's figure is ``rmse["test_official_window"]``.
OFFICIAL = dataclasses.replace(BENCHMARK, start="window", init_window=50)
OFFICIAL_SPLIT = "test_official_window"
DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / BENCHMARK.folder


def candidates(spill_rate: float = MAX_SPILL_RATE) -> list:
    return [TorricelliOutflow(tank="upper"), TorricelliOutflow(tank="lower"), UpperOverflow(max_rate=spill_rate),
            LowerOverflow(), SensorClip(), OutputSaturation(), DeadZone()]


def free_spill(final: ModelScore, train: Record, tests: dict[str, Record]) -> dict | None:
    """The final model refitted from its values with the spill rate free (up to ``FREE_SPILL_RATE``): its rate and
    test RMSE, and the seconds the fit took; ``None`` where the final model has no ``upper_overflow``. As the rate
    grows the spill becomes instant: the upper level clips at the rim, the overflow as the literature's grey box
    writes it. TR-BDF2 integrates it (the fit's step check chooses it where RK4 is unstable)."""
    if "upper_overflow" not in final.model.effect_names():
        return None
    start, bounded = time.perf_counter(), final.model.effects["upper_overflow"]
    values = {name: float(getattr(bounded, name).detach()) for name in ("c", "h", "s")}
    free = with_effect(final.model, UpperOverflow(**values, max_rate=FREE_SPILL_RATE))
    progress = Budget(f"refitting {final.name} with the spill rate free (up to {FREE_SPILL_RATE:g} 1/s)")
    fit = fit_physics(free, [train], initial_state=Estimate(), start_states=final.train_states, ftol=1e-8,
                      budget=progress)  # no limit: the budget prints its progress lines
    return {"rate": float(free.effects["upper_overflow"].c.detach()), "solver": type(fit.solver).__name__,
            "rmse": {name: BENCHMARK.score(free, record, solver=fit.solver, train_state=fit.initial_states[0])
                     for name, record in tests.items()},
            "seconds": time.perf_counter() - start}


def hypotheses(final: ModelScore, estimation: Record, train: Record, validation: Record,
               tests: dict[str, Record]) -> list[dict]:
    """The hypotheses tried beside the diagnosis (:func:`~torchpaml.leaderboard.hypothesis_entry`), from the final
    model's values and initial state: the sensor's zero off the outlet (:class:`tanks.SensorOffset`), scored on
    validation, and the final model refitted on the whole estimation record (validation part included)."""
    return [hypothesis_entry(BENCHMARK, "hypothesis", "sensor_offset", copy.deepcopy(final.model) + SensorOffset(),
                             [train], tests, initial_state=Estimate(), baseline=final, validation=[validation],
                             start_states=final.train_states),
            hypothesis_entry(BENCHMARK, "protocol", "the final grey box refitted on the whole estimation record",
                             copy.deepcopy(final.model), [estimation], tests, initial_state=Estimate(),
                             start_states=final.train_states)]


def measured(models: list[dict], spill: dict | None, validation: float, tried: list[dict]) -> tuple[dict, tuple]:
    """The protocol's own figures beside the registry's rule, for the goal's evidence: the final grey box's RMSE on
    the held-out quarter of the estimation record (V), the spill left free (its test RMSE and rate), and how far the
    validation gains of the hypotheses tried predict their test figures (:func:`validation_agreement`, with its
    computed sentence)."""
    evidence = {"validation": validation}
    if spill is not None:
        evidence |= {"free_spill": spill["rmse"]["test"], "free_spill_rate": spill["rate"]}
    agreement, sentence = agreement_evidence(validation_agreement(tried, models, "test"), "test", BENCHMARK.unit)
    return evidence | agreement, (sentence,) if agreement else ()


def user_physics() -> TwoTanks:
    """The user's linear two-tank physics, where every fit starts: time constants of 100 s, a gain of 2 V/V."""
    return TwoTanks(k1=0.01, k2=0.01, k3=0.01, k4=0.02, learn=("k1", "k3", "k4"))


def diagnosed(train: Record, validation: Record, spill_rate: float = MAX_SPILL_RATE) -> Diagnosis:
    """The diagnosis of the leaderboard's tanks run (also ``benchmarks/bench_same_answer.py``'s)."""
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    return diagnose(user_physics(), candidates(spill_rate), train, validation, initial_state=Estimate(), alpha=alpha)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--data", type=Path, default=DATA, help=f"the cascaded_tanks folder (default {DATA})")
    parser.add_argument("--discover", action="store_true",
                        help="also discover what the linear TwoTanks miss, without the user effects")
    parser.add_argument("--free-spill", action="store_true",
                        help=f"leave the spill rate free (up to {FREE_SPILL_RATE:g} 1/s; a fast spill is stiff and the "
                             f"fit integrates it with the implicit TR-BDF2) instead of bounding it at one sample "
                             f"interval ({MAX_SPILL_RATE} 1/s), where RK4 resolves it")
    args = parser.parse_args(argv)
    if not (args.data / "estimation.csv").is_file():
        parser.error(f"{args.data} has no estimation.csv; point --data at shared/data/cascaded_tanks")
    start = time.perf_counter()
    estimation = Record.from_csv(args.data / f"{BENCHMARK.train}.csv", "estimation", hold=BENCHMARK.hold)
    tests = {name: Record.from_csv(args.data / f"{name}.csv", name, hold=BENCHMARK.hold) for name in BENCHMARK.tests}
    train, validation = BENCHMARK.split(estimation)
    spill_rate = FREE_SPILL_RATE if args.free_spill else MAX_SPILL_RATE
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    diagnosis = diagnosed(train, validation, spill_rate)
    physics = user_physics()
    write_report(diagnosis, args.out / "diagnosis")
    models = ladder_entries(BENCHMARK, diagnosis, tests)
    for row, step in zip(models, diagnosis.ladder.steps, strict=True):
        row["initial_state"] = step.train_states[0].tolist()
        row["nrmse"] = {name: value / float(tests[name].y.std()) for name, value in row["rmse"].items()}
        row["rmse"][OFFICIAL_SPLIT] = OFFICIAL.scores(step, tests)["test"]
    final, alarm = diagnosis.ladder.final, diagnosis.hybrids[-1].adequacy
    hybrid = hybrid_entry(BENCHMARK, final, [train], alpha, alarm, tests)
    spill = None if args.free_spill else free_spill(final, train, tests)
    if spill is not None:
        print(f"spill rate free: {spill['rate']:.3g} 1/s, test RMSE {spill['rmse']['test']:.3f} V "
              f"({spill['seconds']:.0f} s)", flush=True)
    y_validation = simulate_record(final.model, estimation, final.train_states[0], solver=final.solver)[0][len(train.t):]
    validation_rmse = float((validation.y - y_validation)[:, 0].square().mean().sqrt())
    result = {"schema_version": SCHEMA_VERSION, "benchmark": BENCHMARK.name, "protocol": BENCHMARK.protocol(),
              "found": diagnosis.ladder.found, "models": models, "hybrid": hybrid,
              "hybrids": diagnosis_to_dict(diagnosis)["hybrid"], "free_spill": spill,
              "tried": [*tried_entries(BENCHMARK, diagnosis, tests),
                        *hypotheses(final, estimation, train, validation, tests)]}
    evidence, notes = measured(models, spill, validation_rmse, result["tried"])
    result["goal"] = diagnosed_goal(BENCHMARK, diagnosis, models, hybrid, evidence=evidence, notes=notes)
    result["seconds"] = time.perf_counter() - start
    if args.discover:
        found = diagnose(physics, [], train, validation, initial_state=Estimate(), discovery=Discoverer(),
                         prober=None).discovery
        rmse = BENCHMARK.scores(found.discovered or found.physics, tests)
        written = discovery_to_dict(found)
        result["discovery"] = {"expression": written["expression"], "terms": written["terms"],
                               "recommended": written["recommended"], "reason": written["reason"], "rmse": rmse,
                               "nrmse": {name: value / float(tests[name].y.std()) for name, value in rmse.items()}}
        print(f"discovered {found.expression}: test RMSE {rmse['test']:.3f} V", flush=True)
        result["seconds"] = time.perf_counter() - start
    for ranking in diagnosis.ladder.rankings:
        print(ranking_table(ranking))
    return write_result(args.out, result, diagnosis.verdict)


if __name__ == "__main__":
    with progress_lines(Path(__file__).parent.name):  # the diagnosis' steps on stderr, with the seconds
        main()
