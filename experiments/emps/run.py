r"""EMPS (a measured positioning system): diagnose a user's rigid body, add what is found, score on the test run.

    python experiments/emps/run.py --out DIR [--data PATH] [--shortlist K]

The official protocol (``shared/data/emps/README.md``): ``estimation.csv`` for training, its last
:data:`VALIDATION_SHARE` held out inside it for validation (the ranking's and the residual's choices use those
only); ``test.csv`` is touched once, for the reported figure. The model is simulated in free run from the motor
voltage ``vir`` to the motor position ``qm``; its state is estimated on the first :data:`INIT_SAMPLES` samples of the
test record (the ``nonlinear_benchmarks`` loader's window) and the RMSE of the position over the rest is in mm. Beside
it, ``test_velocity``: the RMSE of the model's velocity in mm/s against the central differences of the measured
position (the records hold no measured velocity), a measure that a force error does not integrate into a drift.

1. The physics: :class:`rigid_body.RigidBody`, $M\ddot q = g_\tau v_{ir} - F_v\dot q$, from $M = 100$ kg,
   $F_v = 100$ N s/m.
2. :func:`~torchpaml.diagnose` with the library's forces that a carriage on a guide can have (:func:`candidates`:
   an offset, Coulomb friction, quadratic damping; a free carriage has no spring, so the position-dependent
   effects are left out), each record's initial state estimated (``Estimate()``): the ladder adds what the
   validation asks for.
3. Every rung is scored on the test record; the final one with the orthogonal residual on top too
   (:mod:`leaderboard`).

Writes ``DIR/emps.json`` (the leaderboard's fields, :mod:`leaderboard`, with what limits the figure in ``goal``
(:func:`goal`), plus ``found`` and ``friction {forward_N, backward_N}``: the Coulomb friction against each direction of
motion, the offset included) and ``DIR/diagnosis/``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the leaderboard's contract, beside the experiments
sys.path.insert(0, str(Path(__file__).resolve().parent))

from leaderboard import (SCHEMA_VERSION, arguments, goal_entry, hybrid_entry, model_entry, probe_entries, protocol,
                         write_result)  # noqa: E402
from rigid_body import RigidBody  # noqa: E402

import torch  # noqa: E402

from torchpaml.cli.progress import progress_lines  # noqa: E402
from torchpaml import (
    Auto,
    ConstantForce,
    CoulombFriction,
    Estimate,
    QuadraticDamping,
    Ranker,
    Record,
    diagnose,
    estimate_initial_state,
    simulate_record,
    write_report,
)
from torchpaml.report import diagnosis_to_dict

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "emps"
#: The share of the estimation record held out for validation, at its end.
VALIDATION_SHARE = 0.2
#: Samples of a test record that may set the model's initial state (the benchmark's loader).
INIT_SAMPLES = 20
#: The leaderboard's goal on the test record, mm.
GOAL = 4.6


def candidates() -> list:
    """The library's position-independent forces: what a rigid carriage on a guide can miss."""
    return [ConstantForce(), CoulombFriction(), QuadraticDamping()]


def split(record: Record) -> tuple[Record, Record]:
    cut = round((1 - VALIDATION_SHARE) * len(record.t))
    return record.window(0, cut, "train"), record.window(cut, None, "validation")


def position_rmse_mm(record: Record, y_model) -> float:
    """The benchmark's metric: RMSE of the position in mm after the initialisation window."""
    error = (record.y - y_model)[INIT_SAMPLES:, 0]
    return 1000 * float(error.square().mean().sqrt())


def velocity_rmse_mm_s(record: Record, states) -> float:
    """RMSE in mm/s of the model's velocity (its second state; ``states`` (time, n_state)) against the central
    differences of the measured position, after the initialisation window."""
    measured = torch.gradient(record.y[:, 0], spacing=(record.t,))[0]
    return 1000 * float((measured - states[:, 1])[INIT_SAMPLES:].square().mean().sqrt())


def test_scores(score, record: Record) -> dict[str, float]:
    """A fitted model's figures on ``record``: ``test``, the position's RMSE in mm, and ``test_velocity``, the
    velocity's in mm/s (:func:`velocity_rmse_mm_s`), from the state its first samples set."""
    x0 = test_start(score.model, score.solver, record)
    y = simulate_record(score.model, record, x0, solver=score.solver)[0]
    states = score.fitted.states(record, x0).reshape(len(record.t), -1)
    return {"test": position_rmse_mm(record, y), "test_velocity": velocity_rmse_mm_s(record, states)}


def test_start(model, solver, record: Record):
    """The state that best explains the first :data:`INIT_SAMPLES` samples, the parameters fixed."""
    return estimate_initial_state(model, record, INIT_SAMPLES, solver=Auto(start=solver))


def friction(parameters: dict[str, float]) -> dict[str, float]:
    """The Coulomb friction in N against motion forward ($F_c - f_0$) and backward ($F_c + f_0$): the offset $f_0$ and
    the symmetric $F_c$ together are Coulomb friction that differs with the direction of motion."""
    mass = parameters["M"]
    coulomb, offset = mass * parameters.get("coulomb_friction.Fc", 0.0), mass * parameters.get("constant_force.f0", 0.0)
    return {"forward_N": coulomb - offset, "backward_N": coulomb + offset}


def goal(final, parts: list[Record], models: list[dict], hybrid: dict) -> dict:
    """:data:`GOAL` on test, and what limits the figure: the model class where the final grey box drifts as far on the
    estimation record's own parts (each started from its first :data:`INIT_SAMPLES` samples) as on test, so that
    what it misses is in the estimation record too, not only in the test's unmeasured force pulses."""
    evidence = {}
    for record in parts:
        y = simulate_record(final.model, record, test_start(final.model, final.solver, record), solver=final.solver)[0]
        evidence[record.name] = position_rmse_mm(record, y)
    evidence["test"] = models[-1]["rmse"]["test"]
    explanation = (f"the model class: the final grey box drifts {evidence['train']:.2g} mm on the estimation record's "
                   f"training part and {evidence['validation']:.2g} mm on its validation part, both free runs from "
                   f"the same {INIT_SAMPLES}-sample window as the test ({evidence['test']:.2g} mm): the force it misses "
                   f"acts during the estimation run too, which has no external pulses. An integrating plant turns "
                   f"any such force error into a drift of the position")
    return goal_entry(GOAL, "test", models, hybrid, "model class", evidence, explanation)


def main(argv: list[str] | None = None) -> dict:
    parser = arguments(__doc__, DATA)
    args = parser.parse_args(argv)
    if not (args.data / "estimation.csv").is_file():
        parser.error(f"{args.data} has no estimation.csv; point --data at shared/data/emps")
    start = time.perf_counter()
    train, validation = split(Record.from_csv(args.data / "estimation.csv", "estimation"))
    test = Record.from_csv(args.data / "test.csv", "test")
    alpha = 1.05 * max(float(r.u.abs().max()) for r in (train, validation))
    diagnosis = diagnose(RigidBody(M=100.0, Fv=100.0), candidates(), train, validation,
                         ranker=Ranker(shortlist=args.shortlist), initial_state=Estimate(), alpha=alpha)
    write_report(diagnosis, args.out / "diagnosis")
    content = diagnosis_to_dict(diagnosis)  # its uncertainty: null where a parameter is not determined
    models = []
    for step, rung in zip(diagnosis.ladder.steps, content["ladder"], strict=True):
        models.append(model_entry(step, rung["uncertainty"], test_scores(step, test)))
        print(f"{step.name}: test RMSE {models[-1]['rmse']['test']:.2f} mm, velocity "
              f"{models[-1]['rmse']['test_velocity']:.2f} mm/s", flush=True)
    final, alarm = diagnosis.ladder.final, diagnosis.hybrids[-1].adequacy
    hybrid = hybrid_entry(final, [train], alpha, alarm,
                          {"test": (test, test_start(final.model, final.solver, test))}, position_rmse_mm)
    print(f"{hybrid['model']}: test RMSE {hybrid['rmse']['test']} mm, accepted: {hybrid['accepted']}", flush=True)
    result = {"schema_version": SCHEMA_VERSION, "benchmark": "emps",
              "protocol": protocol("estimation (its last 20 % for validation)", ["test"], INIT_SAMPLES,
                                   "RMSE of the position, free run from vir", "mm"),
              "found": diagnosis.ladder.added, "friction": friction(final.parameters), "models": models,
              "hybrid": hybrid, "goal": goal(final, [train, validation], models, hybrid),
              "probes": probe_entries(diagnosis.probes, lambda score: test_scores(score, test))}
    result["seconds"] = time.perf_counter() - start
    return write_result(args.out, result, diagnosis.verdict)


if __name__ == "__main__":
    with progress_lines(Path(__file__).parent.name):  # the diagnosis' steps on stderr, with the seconds
        main()
