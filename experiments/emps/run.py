r"""EMPS (a measured positioning system): diagnose a user's rigid body, add what is found, score on the test run.

    python experiments/emps/run.py --out DIR [--data PATH] [--shortlist K]

The protocol is the registered :data:`BENCHMARK` (:mod:`torchpaml.leaderboard`; the data:
``shared/data/emps/README.md``): ``estimation.csv`` for training, its last 20 % held out inside it for validation
(the ranking's and the residual's choices use those only); ``test.csv`` is touched once, for the reported figure.
The model is simulated in free run from the motor voltage ``vir`` to the motor position ``qm``; its state is
estimated on the first 20 samples of the test record (the ``nonlinear_benchmarks`` loader's window) and the RMSE of
the position over the rest is in mm. Beside
it, ``test_velocity``: the RMSE of the model's velocity in mm/s against the central differences of the measured
position (the records hold no measured velocity; :meth:`~torchpaml.leaderboard.Benchmark.velocity_score`), a measure
that a force error does not integrate into a drift.

1. The physics: :class:`rigid_body.RigidBody`, $M\ddot q = g_\tau v_{ir} - F_v\dot q$, from $M = 100$ kg,
   $F_v = 100$ N s/m.
2. :func:`~torchpaml.diagnose` with the library's forces that a carriage on a guide can have (:func:`candidates`:
   an offset, Coulomb friction, quadratic damping; a free carriage has no spring, so the position-dependent
   effects are left out), each record's initial state estimated (``Estimate()``): the ladder adds what the
   validation asks for.
3. Every rung is scored on the test record; the final one with the orthogonal residual on top too, and every probe's
   extension (:mod:`torchpaml.leaderboard`).
4. A hypothesis of the protocol, tried beside the diagnosis and not kept (``tried``, stage ``protocol``): the final
   grey box refitted on the whole estimation record, validation part included.

Writes ``DIR/emps.json`` (the leaderboard's fields, :mod:`torchpaml.leaderboard`, ``rmse: {test, test_velocity}``,
with what limits the figure in ``goal``: the registry's rule, :func:`~torchpaml.leaderboard.diagnosed_goal`, with
:func:`measured`'s figures; plus ``found`` and ``friction {forward_N, backward_N}``: the Coulomb friction against
each direction of motion, the offset included) and ``DIR/diagnosis/``.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path

from rigid_body import RigidBody  # the user's physics, beside this script

from torchpaml import (ConstantForce, CoulombFriction, Diagnosis, Estimate, QuadraticDamping, Ranker, Record, diagnose,
                       write_report)
from torchpaml.cli.progress import progress_lines
from torchpaml.leaderboard import (SCHEMA_VERSION, agreement_evidence, arguments, benchmark, diagnosed_goal,
                                   hybrid_entry, hypothesis_entry, ladder_entries, tried_entries, validation_agreement,
                                   write_result)

BENCHMARK = benchmark("emps")
DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / BENCHMARK.folder


def candidates() -> list:
    """The library's position-independent forces: what a rigid carriage on a guide can miss."""
    return [ConstantForce(), CoulombFriction(), QuadraticDamping()]


def friction(parameters: dict[str, float]) -> dict[str, float]:
    """The Coulomb friction in N against motion forward ($F_c - f_0$) and backward ($F_c + f_0$): the offset $f_0$ and
    the symmetric $F_c$ together are Coulomb friction that differs with the direction of motion."""
    mass = parameters["M"]
    coulomb, offset = mass * parameters.get("coulomb_friction.Fc", 0.0), mass * parameters.get("constant_force.f0", 0.0)
    return {"forward_N": coulomb - offset, "backward_N": coulomb + offset}


def measured(final, parts: list[Record], models: list[dict], tried: list[dict]) -> tuple[dict, tuple]:
    """The protocol's own figures beside the registry's rule, for the goal's evidence: the final grey box's drift
    (mm) on each part of the estimation record, each a free run from the same first samples as the test, and how
    far the validation gains of the hypotheses tried predict their test figures (:func:`validation_agreement`, with
    its computed sentence)."""
    evidence = {record.name: BENCHMARK.score(final.model, record, solver=final.solver) for record in parts}
    agreement, sentence = agreement_evidence(validation_agreement(tried, models, "test"), "test", BENCHMARK.unit)
    return evidence | agreement, (sentence,) if agreement else ()


def diagnosed(train: Record, validation: Record, shortlist: int = 2) -> Diagnosis:
    """The diagnosis of the leaderboard's EMPS run (also ``benchmarks/bench_same_answer.py``'s)."""
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    return diagnose(RigidBody(M=100.0, Fv=100.0), candidates(), train, validation, ranker=Ranker(shortlist=shortlist),
                    initial_state=Estimate(), alpha=alpha)


def main(argv: list[str] | None = None) -> dict:
    parser = arguments(BENCHMARK, __doc__, DATA)
    args = parser.parse_args(argv)
    if not (args.data / f"{BENCHMARK.train}.csv").is_file():
        parser.error(f"{args.data} has no {BENCHMARK.train}.csv; point --data at shared/data/{BENCHMARK.folder}")
    start = time.perf_counter()
    estimation = Record.from_csv(args.data / f"{BENCHMARK.train}.csv", "estimation")
    train, validation = BENCHMARK.split(estimation)
    tests = {name: Record.from_csv(args.data / f"{name}.csv", name) for name in BENCHMARK.tests}
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    diagnosis = diagnosed(train, validation, args.shortlist)
    write_report(diagnosis, args.out / "diagnosis")
    models = ladder_entries(BENCHMARK, diagnosis, tests)  # with test_velocity: the registry's velocity="velocity"
    final, alarm = diagnosis.ladder.final, diagnosis.hybrids[-1].adequacy
    hybrid = hybrid_entry(BENCHMARK, final, [train], alpha, alarm, tests)
    print(f"{hybrid['model']}: test RMSE {hybrid['rmse']['test']} mm, accepted: {hybrid['accepted']}", flush=True)
    whole = hypothesis_entry(BENCHMARK, "protocol", "the final grey box refitted on the whole estimation record",
                             copy.deepcopy(final.model), [estimation], tests, initial_state=Estimate(),
                             start_states=final.train_states)
    tried = [*tried_entries(BENCHMARK, diagnosis, tests), whole]
    result = {"schema_version": SCHEMA_VERSION, "benchmark": BENCHMARK.name, "protocol": BENCHMARK.protocol(),
              "found": diagnosis.ladder.found, "friction": friction(final.parameters), "models": models,
              "hybrid": hybrid, "tried": tried}
    evidence, notes = measured(final, [train, validation], models, tried)
    result["goal"] = diagnosed_goal(BENCHMARK, diagnosis, models, hybrid, evidence=evidence, notes=notes)
    result["seconds"] = time.perf_counter() - start
    return write_result(args.out, result, diagnosis.verdict)


if __name__ == "__main__":
    with progress_lines(Path(__file__).parent.name):  # the diagnosis' steps on stderr, with the seconds
        main()
