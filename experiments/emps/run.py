r"""EMPS (a measured positioning system): diagnose a user's rigid body, add what is found, score on the test run.

    python experiments/emps/run.py --out DIR [--data PATH] [--shortlist K]

The official protocol (``shared/data/emps/README.md``): ``estimation.csv`` for training, its last
:data:`VALIDATION_SHARE` held out inside it for validation (the ranking's and the residual's choices use those
only); ``test.csv`` is touched once, for the reported figure. The model is simulated in free run from the motor
voltage ``vir`` to the motor position ``qm``; its state is estimated on the first :data:`INIT_SAMPLES` samples of the
test record (the ``nonlinear_benchmarks`` loader's window) and the RMSE of the position over the rest is in mm.

1. The physics: :class:`rigid_body.RigidBody`, $M\ddot q = g_\tau v_{ir} - F_v\dot q$, from $M = 100$ kg,
   $F_v = 100$ N s/m.
2. :func:`~torchpaml.diagnose` with the library's forces that a carriage on a guide can have (:func:`candidates`:
   an offset, Coulomb friction, quadratic damping; a free carriage has no spring, so the position-dependent
   effects are left out), each record's initial state estimated (``Estimate()``): the ladder adds what the
   validation asks for.
3. Every rung is scored on the test record; the final one with the orthogonal residual on top too
   (:mod:`leaderboard`).

Writes ``DIR/emps.json`` (the leaderboard's fields, :mod:`leaderboard`, plus ``found``) and ``DIR/diagnosis/``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the leaderboard's contract, beside the experiments
sys.path.insert(0, str(Path(__file__).resolve().parent))

from leaderboard import SCHEMA_VERSION, arguments, hybrid_entry, model_entry, protocol, write_result  # noqa: E402
from rigid_body import RigidBody  # noqa: E402

from torchpaml.cli.progress import progress_lines  # noqa: E402
from torchpaml import (  # noqa: E402
    Auto,
    ConstantForce,
    CoulombFriction,
    Estimate,
    QuadraticDamping,
    Ranker,
    Record,
    diagnose,
    diagnosis_to_dict,
    estimate_initial_state,
    simulate_record,
    write_report,
)

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "emps"
#: The share of the estimation record held out for validation, at its end.
VALIDATION_SHARE = 0.2
#: Samples of a test record that may set the model's initial state (the benchmark's loader).
INIT_SAMPLES = 20


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


def test_start(model, solver, record: Record):
    """The state that best explains the first :data:`INIT_SAMPLES` samples, the parameters fixed."""
    return estimate_initial_state(model, record, INIT_SAMPLES, solver=Auto(start=solver))


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
        y = simulate_record(step.model, test, test_start(step.model, step.solver, test), solver=step.solver)[0]
        models.append(model_entry(step, rung["uncertainty"], {"test": position_rmse_mm(test, y)}))
        print(f"{step.name}: test RMSE {models[-1]['rmse']['test']:.2f} mm", flush=True)
    final, alarm = diagnosis.ladder.final, diagnosis.hybrids[-1].adequacy
    hybrid = hybrid_entry(final, [train], alpha, not alarm.inadequate, alarm.message,
                          {"test": (test, test_start(final.model, final.solver, test))}, position_rmse_mm)
    print(f"{hybrid['model']}: test RMSE {hybrid['rmse']['test']} mm, accepted: {hybrid['accepted']}", flush=True)
    result = {"schema_version": SCHEMA_VERSION, "benchmark": "emps",
              "protocol": protocol("estimation (its last 20 % for validation)", ["test"], INIT_SAMPLES,
                                   "RMSE of the position, free run from vir", "mm"),
              "found": diagnosis.ladder.added, "models": models, "hybrid": hybrid,
              "seconds": time.perf_counter() - start}
    return write_result(args.out, result, diagnosis.verdict)


if __name__ == "__main__":
    with progress_lines(Path(__file__).parent.name):  # the diagnosis' steps on stderr, with the seconds
        main()
