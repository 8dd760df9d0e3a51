"""``torchpaml simulate``, ``export``, ``track`` and ``paper`` (argparse), and the top-level help that lists every
command."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from torchpaml._errors import ConfigurationError
from torchpaml.cli.progress import progress_lines

__all__ = ["run_command"]

DESCRIPTION = """Physics-augmented learning of input-driven dynamical systems.

commands:
  diagnose   find the effect a physics model is missing (torchpaml diagnose --help)
  fleet      diagnose every unit of a fleet on Ray, and see which ones changed (torchpaml fleet --help)
  simulate   write noisy measurements of library physics plus effects, or (--model) a saved model's prediction
  export     write a saved model as FMUs, an ONNX step and code (torchpaml export --help)
  track      follow a running device on a saved model and flag when it stops matching (torchpaml track --help)
  paper      reproduce the paper's numerical results
  fit, validate, test
             train, validate or test a Lightning system from a config (torchpaml fit --help)
"""


def _paper(args: argparse.Namespace) -> None:
    from torchpaml._paper import reproduce
    from torchpaml._render.tables import paper_table

    start = time.perf_counter()
    with progress_lines(f"{args.prog} paper", enabled=not args.quiet):
        report = reproduce(args.alpha or [4.0, 10.0], seeds=args.seeds)
    report["wall_time_s"] = time.perf_counter() - start
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(report, indent=2))
    table = paper_table(report)
    (out / "table.md").write_text(table + "\n")
    print(table)
    print(f"\n{args.seeds} seed(s), {report['wall_time_s']:.1f} s; wrote {out / 'results.json'} and {out / 'table.md'}")


def _simulate(args: argparse.Namespace) -> None:
    if args.model is not None:
        return _predict(args)
    if args.physics is None:
        raise ConfigurationError("simulate needs --physics (library physics to simulate) or --model (a saved model to "
                                 "run on --data)")
    from torchpaml._data import Simulated
    from torchpaml._physics.registry import build_model, parse_assignments

    model = build_model(args.physics, parse_assignments(args.set, "--set"), parse_assignments(args.effect, "--effect"))
    source = Simulated(model, args.signal, args.amplitude, [args.seed], args.duration, args.dt, args.omega,
                       noise=args.noise)
    (record,) = source.experiments()
    record.metadata["model"] = model.display_name
    record.metadata["parameters"] = model.physical_parameters()
    print(f"wrote {record.to_csv(args.out)}: {len(record.t)} samples of {model.display_name}")


def _predict(args: argparse.Namespace) -> None:
    """``simulate --model FILE --data CSV --out CSV``: the saved model's outputs and states on the record's input
    (:func:`~torchpaml.predict`), with ``--band LEVEL`` its output band."""
    from torchpaml._data import Record
    from torchpaml._model import load_model, predict
    from torchpaml._render.prediction import write_prediction

    if args.data is None:
        raise ConfigurationError("simulate --model needs --data: a CSV with t and the model's input columns")
    model = load_model(args.model, trust=args.trust)
    record = Record.from_csv(args.data, channels=(model.inputs, model.outputs), hold=args.hold,
                             with_outputs=False)
    prediction = predict(model, record, args.band)
    path = write_prediction(model, record, prediction, args.out)
    print(f"wrote {path}: {len(record.t)} samples of {model.physics.equation()} from {args.model}")


def _simulate_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--physics", help="library physics: oscillator or pendulum")
    parser.add_argument("--model", help="a saved model (model.pt of torchpaml diagnose) to run on --data instead")
    parser.add_argument("--data", help="with --model: CSV of t and the model's inputs (outputs, where present, "
                        "start the record as the diagnosis did)")
    parser.add_argument("--band", type=float, metavar="LEVEL",
                        help="with --model: add the output band at this coverage (0.95) from the fit's covariance")
    parser.add_argument("--hold", choices=["foh", "zoh"], help="with --model: how the input moved between samples "
                        "(default: the file's metadata, else foh)")
    parser.add_argument("--set", action="append", metavar="NAME=VALUE", help="a parameter value (repeat)")
    parser.add_argument("--effect", action="append", metavar="EFFECT=STRENGTH",
                        help="add a library effect at this strength, e.g. cubic_stiffness=2 (repeat)")
    parser.add_argument("--signal", default="pseudorandom", choices=["sine", "cosine", "pseudorandom", "multisine"])
    parser.add_argument("--amplitude", type=float, default=1.0, help="peak input (default 1)")
    parser.add_argument("--omega", type=float, default=1.0, help="sine frequency, rad/s (default 1)")
    parser.add_argument("--duration", type=float, default=80.0, help="record length, s (default 80)")
    parser.add_argument("--dt", type=float, default=0.01, help="sampling interval, s (default 0.01)")
    parser.add_argument("--noise", type=float, default=0.0, help="output noise std as a fraction of RMS(y)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the signal and the noise")
    _trust_argument(parser)
    parser.add_argument("--out", required=True, help="CSV file to write (header t,u,y; first line # metadata; with "
                        "--model: t, the inputs, the outputs, the states and the band)")
    parser.set_defaults(run=_simulate)


def _export(args: argparse.Namespace) -> None:
    from torchpaml._export import export_model
    from torchpaml._model import load_model

    written = export_model(load_model(args.model, trust=args.trust), fmu=args.fmu, fmu_me=args.fmu_me, onnx=args.onnx,
                           code=args.code)
    print("wrote " + ", ".join(str(p) for p in written))


def _export_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", required=True, help="a saved model (model.pt of torchpaml diagnose)")
    parser.add_argument("--fmu", help="FMU to write (FMI 2.0 co-simulation; needs a C compiler and FMPy's headers)")
    parser.add_argument("--fmu-me", help="FMU to write as FMI 2.0 model exchange, a sampled-data model at the "
                        "records' sampling interval: what FMPy's simulate_fmu with an input table runs as the model runs")
    parser.add_argument("--onnx", help="ONNX file to write: the model's one-step map")
    parser.add_argument("--code", help="code to write, the language by the suffix: .py, .c or .h, .tex")
    _trust_argument(parser)
    parser.set_defaults(run=_export)


def _track_fleet(args: argparse.Namespace) -> None:
    """``track --units DIR``: every unit on its own model, on Ray (:mod:`torchpaml.cli.fleet_track`)."""
    from torchpaml.cli.fleet_track import FLEET_TRACK_FILE, fleet_table, track_fleet

    given = [name for name in ("model", "data", "noise", "x0") if getattr(args, name)]
    if given:
        raise ConfigurationError(f"track --units takes each unit's model.pt and stream.csv from its folder: drop "
                                 f"{', '.join('--' + n for n in given)} (noise and x0 are per device)")
    if args.workers < 1:
        raise ConfigurationError(f"--workers must be at least 1, got {args.workers}")
    options = {"window": args.window, "alpha": args.alpha, "attribution": args.attribution, "hold": args.hold,
               "process": tuple(args.process_noise) if args.process_noise else None}
    with progress_lines(f"{args.prog} track", enabled=not args.quiet):
        fleet = track_fleet(Path(args.units), Path(args.out), options, tuple(args.trust), address=args.address,
                            workers=args.workers)
    print(fleet_table(fleet["units"]), end="")
    changed = [row["unit"] for row in fleet["units"] if row["changed"]]
    print(f"{len(fleet['units'])} units in {fleet['seconds']:.0f} s; changed: {changed or 'none'}; wrote "
          f"{Path(args.out) / FLEET_TRACK_FILE}, fleet_track.md and one folder per unit")


def _track(args: argparse.Namespace) -> None:
    from torchpaml._data import Record
    from torchpaml._model import load_model
    from torchpaml._render.tracking import write_tracking
    from torchpaml._track import track

    if args.units:
        return _track_fleet(args)
    if not (args.model and args.data):
        raise ConfigurationError("track needs --model and --data (one device), or --units (a fleet: one folder per unit "
                                 "with model.pt and stream.csv)")
    model = load_model(args.model, trust=args.trust)
    record = Record.from_csv(args.data, channels=(model.inputs, model.outputs), hold=args.hold,
                             missing_outputs=True)
    options = {"window": args.window, "alpha": args.alpha, "attribution": args.attribution,
               "hold": args.hold or record.metadata.get("hold") or model.hold}
    for option, key in (("noise", "noise"), ("x0", "x0"), ("process_noise", "process")):
        if getattr(args, option):
            options[key] = tuple(getattr(args, option))
    with progress_lines(f"{args.prog} track", enabled=not args.quiet):
        tracking = track(model, record, **options)
    path = write_tracking(tracking, args.out)
    alarms = "; ".join(f"t = {a.t:.4g} s ({a.parameter or 'parameter undetermined'})" for a in tracking.alarms)
    print(f"wrote {path}: {len(record.t)} samples in {tracking.seconds:.3g} s ({tracking.missing} missing), "
          f"{len(tracking.alarms)} alarm(s){': ' + alarms if alarms else ''}")


def _trust_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--trust", action="append", default=[], metavar="PACKAGE",
                        help="a package whose classes the model file may name besides torchpaml's (your own physics; "
                        "repeat); a file naming any other is refused before anything is imported")


def _track_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", help="a saved model (model.pt of torchpaml diagnose)")
    parser.add_argument("--data", help="CSV of the stream: t, the model's inputs and outputs (an empty or NaN output "
                        "cell is a missing measurement, predicted through)")
    parser.add_argument("--out", required=True, help="folder for track.json and track.png (with --units: one folder "
                        "per unit, fleet_track.json and fleet_track.md)")
    parser.add_argument("--units", help="a fleet instead of --model and --data: a folder with one sub-folder per unit, "
                        "each holding model.pt and stream.csv, tracked on Ray")
    parser.add_argument("--address", help="with --units: a running Ray cluster to join; default a local Ray")
    parser.add_argument("--workers", type=int, default=2, help="with --units: cores of the local Ray (default 2)")
    parser.add_argument("--window", type=float, default=0.5, help="the detector's window, s; the start is estimated "
                        "on the stream's first window (default 0.5)")
    parser.add_argument("--alpha", type=float, default=1e-9,
                        help="the detector's false-alarm probability per window (default 1e-9: at 1 kHz at most "
                        "3.6e-3 false alarms an hour)")
    parser.add_argument("--attribution", type=float, default=1.0,
                        help="seconds after an alarm on which the parameter that moved is named (default 1)")
    parser.add_argument("--noise", type=float, action="append", metavar="STD",
                        help="an output's noise standard deviation (repeat per output; default: the model's)")
    parser.add_argument("--x0", type=float, action="append", metavar="VALUE",
                        help="a known initial state (repeat per state; default: estimated from the first window)")
    parser.add_argument("--process-noise", type=float, action="append", metavar="STD",
                        help="each state's process noise standard deviation per sample (repeat per state, or once "
                        "for all; default: from the fit's parameter uncertainty)")
    parser.add_argument("--hold", choices=["foh", "zoh"], help="how the input moved between samples "
                        "(default: the file's metadata, else the model's)")
    _trust_argument(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    parser.set_defaults(run=_track)


def _paper_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--alpha", type=float, action="append", help="input amplitude (repeat for several)")
    parser.add_argument("--seeds", type=int, default=10, help="number of pseudorandom seeds (default 10)")
    parser.add_argument("--out", required=True, help="output folder for results.json and table.md")
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    parser.set_defaults(run=_paper)


def parser(prog: str = "torchpaml") -> argparse.ArgumentParser:
    """The argparse parser of ``simulate``, ``export``, ``track`` and ``paper`` (the other commands are listed for ``--help``)."""
    top = argparse.ArgumentParser(prog=prog, description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = top.add_subparsers(dest="command", required=True)
    _paper_arguments(commands.add_parser("paper", help="reproduce the paper's numerical results"))
    _simulate_arguments(commands.add_parser("simulate", help="generate noisy measurements from physics + effects"))
    _export_arguments(commands.add_parser("export", help="write a saved model as an FMU, an ONNX step and code"))
    _track_arguments(commands.add_parser("track", help="follow a running device on a saved model"))
    return top


def run_command(argv: list[str], prog: str = "torchpaml") -> None:
    """Parse ``argv`` (``simulate ...``, ``export ...``, ``track ...`` or ``paper ...``) and run the command."""
    top = parser(prog)
    args = top.parse_args(argv)
    args.prog = prog
    if args.command == "paper" and args.seeds < 1:
        top.error("--seeds must be at least 1")
    args.run(args)
