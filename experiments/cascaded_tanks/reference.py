r"""The benchmark document's own grey box, fitted directly: what the ladder's effects can reach together.

    python experiments/cascaded_tanks/reference.py [--data PATH]

The model of ``shared/data/cascaded_tanks/README.md`` with the 10 V clip, composed from the same
user effects the ladder ranks (``tanks.py``):

$$ \dot x_1 = -k_1\sqrt{x_1} + k_4 u, \qquad \dot x_2 = k_2\sqrt{x_1} - k_3\,x_2^{1 - g/2}, \qquad
   y = x_2 - \max(x_2 - 10, 0), $$

that is ``TwoTanks + sqrt_outflow_upper (g = 1, fixed) + sqrt_outflow_lower (g free) + sensor_clip
(w = 1, fixed)``. It is fitted by the one :func:`~torchpaml._fit.fit_physics` on the whole
``estimation`` record, with its initial state, from a start chosen by hand (every rate 0.03 1/s,
k4 = 0.02, levels 5 V), and simulated on ``test`` from that state. The ladder has no such start:
it reaches each rung from the one below. Prints the parameters and the RMSE on both records.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

from run import HOLD
from tanks import SensorClip, TorricelliOutflow, TwoTanks

from torchpaml import Estimate, Record, fit_physics, simulate_record

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "cascaded_tanks"


def benchmark_model():
    """The document's grey box as a composition (module docstring), at the hand-chosen start."""
    return (TwoTanks(0.03, 0.03, 0.03, 0.02, levels=(5.0, 5.0))
            + TorricelliOutflow(1.0, tank="upper", learn=()) + TorricelliOutflow(1.0, tank="lower")
            + SensorClip(1.0, learn=()))


def rmse(model, record: Record, x0, solver) -> float:
    return float((record.y - simulate_record(model, record, x0, solver=solver)[0]).square().mean().sqrt())


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=DATA, help=f"the cascaded_tanks folder (default {DATA})")
    args = parser.parse_args(argv)
    if not (args.data / "estimation.csv").is_file():
        parser.error(f"{args.data} has no estimation.csv; point --data at shared/data/cascaded_tanks")
    estimation = Record.from_csv(args.data / "estimation.csv", "estimation", hold=HOLD)
    test = Record.from_csv(args.data / "test.csv", "test", hold=HOLD)
    model = benchmark_model()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # k2, k4 and the upper level's scale trade: the warning is expected
        fit = fit_physics(model, estimation, initial_state=Estimate(), max_nfev=100)
    x0 = fit.initial_states[0]
    result = {"parameters": fit.parameters, "initial_state": x0.tolist(),
              "rmse": {"estimation": rmse(model, estimation, x0, fit.solver), "test": rmse(model, test, x0, fit.solver)}}
    print(result)
    return result


if __name__ == "__main__":
    main()
