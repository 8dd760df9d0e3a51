"""``torchpaml diagnose``: the diagnosis of a physics model on measured records, from the command line.

``torchpaml diagnose --data TRAIN.csv [MORE.csv ...] --validation VAL.csv [...] --physics oscillator
[--fix omega0=2.0] --out DIR`` fits the library physics (every parameter learnable unless fixed), ranks the
library effects as the missing one, climbs the model ladder, fits the Chebyshev residual on top and writes the report
(diagnosis.json, report.html, figures/, tensorboard/). ``torchpaml diagnose --config FILE.yaml`` takes
the same keys from YAML, where ``physics`` and ``candidates`` may also be user classes
(``class_path``/``init_args``), so user-defined physics and user-defined effects are diagnosed the
same way. ``--discover`` adds the discovery of a force outside the library (``discovery.json``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Literal

import yaml
from jsonargparse import ActionConfigFile, ArgumentError, ArgumentParser

from torchpaml._fit.initial_state import policy_named
from torchpaml._errors import ConfigurationError
from torchpaml._diagnostics.ranking.selection import SelectionRule
from torchpaml._budget import DEFAULT_BUDGET, REFIT_BUDGET, RUNG_FIT_BUDGET
from torchpaml._diagnostics.ranking.beam import BEAM
from torchpaml.cli.progress import progress_lines
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effects import EFFECTS, AbstractEffect
from torchpaml._physics.registry import PHYSICS, parse_assignments

__all__ = ["check_options", "config_mistake", "diagnose_command", "diagnose_parser", "diagnose_to_folder",
           "normalise_arguments", "read_records", "resolve_models", "run_diagnose"]

#: Repeatable flags, spelled ``--fix NAME=VALUE`` on the command line (jsonargparse appends with ``+``).
REPEATED = {"--fix": "--fix+", "--effect": "--effects+", "--term": "--terms+"}
#: Switches that may stand alone: ``--discover`` means ``--discover true``.
SWITCHES = ("--discover", "--discover_always", "--verbose", "--quiet")
#: Options that take one file or several: ``--data a.csv b.csv`` is ``--data '["a.csv", "b.csv"]'``.
RECORD_LISTS = ("--data", "--validation")
#: The keys whose relative paths a config file gives from its own folder.
RECORD_KEYS = ("data", "validation")


def _physics(physics: str | AbstractPhysics, fix: list[str] | None) -> AbstractPhysics:
    if isinstance(physics, str):
        if physics not in PHYSICS:
            raise ConfigurationError(f"unknown physics {physics!r}; choose one of {sorted(PHYSICS)}, or give a class_path "
                             "to your own physics in a --config file")
        physics = PHYSICS[physics]()
        physics.set_learnable(*physics.physical_parameters())
    values = parse_assignments(fix, "--fix")
    unknown = sorted(set(values) - set(physics.physical_parameters()))
    if unknown:
        raise ConfigurationError(f"--fix names unknown parameter(s) {unknown}; {physics.display_name} has "
                         f"{sorted(physics.physical_parameters())}")
    return physics.assign(**values).set_learnable(*values, learn=False)


def _candidates(effects: list[str] | None, candidates: list[AbstractEffect] | None, discover: bool
                ) -> list[AbstractEffect]:
    names = list(EFFECTS) if effects is None and candidates is None else list(effects or [])
    unknown = sorted(set(names) - set(EFFECTS))
    if unknown:
        raise ConfigurationError(f"unknown effect(s) {unknown}; the library has {sorted(EFFECTS)}; put your own effects "
                         "under `candidates:` in a --config file")
    chosen = [EFFECTS[name]() for name in names] + list(candidates or [])
    if not chosen and not discover:
        raise ConfigurationError("no candidate effects: name library effects with --effect, list `candidates:` in --config, "
                         "or run the discovery alone (--discover)")
    return chosen


def resolve_models(physics: str | AbstractPhysics, fix: list[str] | None, effects: list[str] | None,
                   candidates: list[AbstractEffect] | None, discover: bool = False
                   ) -> tuple[AbstractPhysics, list[AbstractEffect]]:
    """The physics (a library name or an object, ``fix`` applied) and the candidate effects, checked (none only
    with ``discover``)."""
    return _physics(physics, fix), _candidates(effects, candidates, discover)


def check_options(shortlist: int, min_share: float, refit_budget: float = REFIT_BUDGET, budget: float | None = None,
                  beam: int = BEAM) -> None:
    """Refuse ranking options that cannot work, before any fit: the stages' own checks (``Ranker``, ``SelectionRule``,
    the diagnosis' budget), their messages naming the command's options."""
    from torchpaml._budget import check_budget
    from torchpaml._diagnostics.ranking.ranker import Ranker

    try:
        SelectionRule(min_share=min_share)
        Ranker(shortlist=shortlist, refit_budget=refit_budget, beam=beam)
        check_budget(budget)
    except ConfigurationError as error:
        raise ConfigurationError(f"--{error}") from None


def diagnose_command(
    data: str | list[str],
    validation: str | list[str],
    out: str,
    physics: str | AbstractPhysics = "oscillator",
    fix: list[str] | None = None,
    effects: list[str] | None = None,
    candidates: list[AbstractEffect] | None = None,
    shortlist: int = 2,
    beam: int = BEAM,
    criterion: Literal["bic", "aic"] = "bic",
    threshold: float = 10.0,
    min_share: float = 0.05,
    initial_state: Literal["rest", "estimate"] = "rest",
    hold: Literal["foh", "zoh"] | None = None,
    discover: bool = False,
    discover_always: bool = False,
    terms: list[str] | None = None,
    probes: bool = True,
    refit_budget: float = REFIT_BUDGET,
    fit_budget: float = RUNG_FIT_BUDGET,
    budget: float | None = DEFAULT_BUDGET,
    verbose: bool = False,
    quiet: bool = False,
) -> dict:
    """Diagnose ``physics`` on the records and write the report into ``out``; returns the ``diagnosis.json`` content.

    Args:
        data: training record(s): one CSV or several (``--data a.csv b.csv``, ``data: [a.csv, b.csv]``), of any
            lengths, each with its own initial state; header ``t,u,y``, ``t,u1,…,y1,…`` or named channels
            (:meth:`~torchpaml.Record.from_csv`).
        validation: validation record(s), likewise (a different input).
        out: output folder (diagnosis.json, figures/, report.html, tensorboard/).
        physics: a library physics name (oscillator, pendulum: every parameter learnable), or in a
            config file a physics object (``class_path``/``init_args``; its own ``learn``).
        fix: ``NAME=VALUE`` parameters held fixed at VALUE (repeat ``--fix``).
        effects: library effects to rank (repeat ``--effect NAME``); default all, or none when ``candidates`` are given.
        candidates: user-defined effects (``AbstractEffect`` subclasses, config only).
        shortlist: how many of the best-scored candidates are refitted.
        beam: how many models climb the ladder side by side, validation choosing their end (1: the greedy ladder).
        criterion: ``bic`` or ``aic`` on the validation record.
        threshold: criterion improvement needed to add an effect.
        min_share: relative fall of the validation mismatch needed to add an effect (0.05: 5 %).
        initial_state: ``rest`` (records start at rest) or ``estimate`` (each record's initial state is
            fitted: with the parameters on training records, alone on validation records).
        hold: how the input moved between samples, ``foh`` (linearly) or ``zoh`` (held constant, as a
            DAC plays a sampled signal); default the CSV metadata's ``"hold"``, else ``foh``.
        discover: also discover a force or rate outside the library on the ladder's last rung: a neural
            rate in the ODE, then its closed form (``discovery.json``, ``discovered_effect.yaml``; any physics).
        discover_always: discover even where the ladder's last rung is complete at the noise level (by default the
            discovery then says so and stops); implies ``discover``.
        terms: the discovery's own terms, sympy strings over the physics' variables (x, v, u for
            second-order physics, else its state names and u), e.g. ``x**2*sign(v)`` (repeat ``--term``).
        probes: where the last rung is not complete at the noise level, probe where its mismatch points: one small
            extension refitted at each place (:class:`~torchpaml.Prober`; ``where_the_mismatch_points`` in
            ``diagnosis.json``); ``--probes false`` skips them.
        refit_budget: each refit may take this many times its rung's own fit, in seconds or in its fit's evaluations
            at the refit's own cost, whichever is longer; one over it stops and is reported undecided, and the ladder
            goes on.
        fit_budget: a rung's fit from the optimum of the refit that found its effect may take this many times that
            refit; one over it stops, the rung keeps the refit's parameters, and the verdict says so.
        budget: seconds for the whole diagnosis, counted from its start, printed in its first progress line
            (default 600; ``null`` in a config: no limit): the fits then running stop, and those not started are not
            run, each said in the verdict (:mod:`torchpaml._budget`).
        verbose: print the traceback of an error raised inside your physics (default: one line).
        quiet: no progress lines (by default each stage, the rung, the candidate refitted, the discovery's
            steps, is printed on stderr with the seconds since the start).
    """
    from torchpaml._render.schema import diagnosis_to_dict

    if Path(out).is_file():
        raise ConfigurationError(f"--out {out} is an existing file; name a folder for the report (it is created if missing)")
    check_options(shortlist, min_share, refit_budget, budget, beam)
    model, chosen = resolve_models(physics, fix, effects, candidates, discover or discover_always)
    stages = _stages(SelectionRule(criterion, threshold, min_share), shortlist, beam, refit_budget, fit_budget, terms,
                     discover or discover_always, discover_always, probes)
    diagnosis = diagnose_to_folder(model, chosen, data, validation, out, hold=hold,
                                   initial_state=policy_named(initial_state), budget=budget, **stages)
    _announce(diagnosis, Path(out))
    return diagnosis_to_dict(diagnosis)


def _announce(diagnosis, out: Path) -> None:
    """Print the first rung's ranking, the verdict and what was written into ``out``."""
    from torchpaml._render.tables import ranking_table

    path = out / "diagnosis.json"
    print(ranking_table(diagnosis.ranking))
    models = ", ".join(str(out / name) for name in ("model.pt", "hybrid.pt") if (out / name).exists())
    print(f"\n{diagnosis.verdict}\n\nwrote {path}, {out / 'report.html'}, figures/, tensorboard/"
          + (f" and {models}" if models else ""))


def _stages(rule: SelectionRule, shortlist: int, beam: int, refit_budget: float, fit_budget: float,
            terms: list[str] | None, discover: bool, always: bool, probes: bool) -> dict:
    """The stages of the command's options, as :func:`~torchpaml.diagnose`'s keywords: the ranker, the discoverer
    (``None`` without ``discover``) and the prober (``None`` without ``probes``)."""
    from torchpaml._diagnostics.discovery.discoverer import Discoverer
    from torchpaml._diagnostics.mismatch.prober import Prober
    from torchpaml._diagnostics.ranking.ranker import Ranker
    from torchpaml._physics.terms import TermLibrary

    ranker = Ranker(rule=rule, shortlist=shortlist, refit_budget=refit_budget, fit_budget=fit_budget, beam=beam)
    discovery = Discoverer(library=TermLibrary(terms=tuple(terms or ())), always=always) if discover else None
    return {"ranker": ranker, "discovery": discovery, "prober": Prober() if probes else None}


def read_records(paths: str | Path | list, hold: str | None = None, physics: AbstractPhysics | None = None) -> list:
    """The CSV record(s) at ``paths`` (one path or a list), each named by its file's stem; where ``physics`` names its
    channels (``input_names``, ``output_names``), a header of those names is read without a metadata line."""
    from torchpaml._data import Record

    paths = [paths] if isinstance(paths, str | Path) else list(paths)
    if not paths:
        raise ConfigurationError("no record given: name one CSV file or more (--data a.csv b.csv)")
    channels = None if physics is None else (physics.input_names, physics.output_names)
    return [Record.from_csv(path, Path(path).stem, hold=hold, channels=channels) for path in paths]


def diagnose_to_folder(physics: AbstractPhysics, candidates: list, data: str | Path | list,
                       validation: str | Path | list, out: str | Path, *, hold: str | None = None, **options):
    """Diagnose ``physics`` on the CSV records ``data`` and ``validation`` (a path or a list of them) and write the
    report into ``out``.

    The one pipeline of a unit's records, from files: ``torchpaml diagnose`` and each task of
    ``torchpaml fleet`` run it. ``hold`` is how the input moved between samples (default: the files' metadata, else
    ``"foh"``); ``options`` go to :func:`~torchpaml.diagnose`.
    """
    from torchpaml._diagnostics.diagnosis import diagnose
    from torchpaml._render.report import write_report

    train, held_out = read_records(data, hold, physics), read_records(validation, hold, physics)
    diagnosis = diagnose(physics, candidates, train, held_out, **options)
    write_report(diagnosis, out)
    return diagnosis


def _record_lists(argv: list[str]) -> list[str]:
    """``--data a.csv b.csv`` (several values after an option of :data:`RECORD_LISTS`) as one JSON list."""
    out, i = [], 0
    while i < len(argv):
        if argv[i] in RECORD_LISTS:
            end = next((j for j in range(i + 1, len(argv)) if argv[j].startswith("--")), len(argv))
            if end - i > 2:
                out.append(f"{argv[i]}={json.dumps(argv[i + 1:end])}")
                i = end
                continue
        out.append(argv[i])
        i += 1
    return out


def normalise_arguments(argv: list[str], switches: tuple[str, ...] = SWITCHES) -> list[str]:
    """``--fix NAME=VALUE`` and ``--effect NAME`` repeated, ``--data a.csv b.csv``, and ``switches`` alone, as
    jsonargparse reads them."""
    argv = _record_lists(argv)
    argv = [f"{a}=true" if a in switches and (i + 1 == len(argv) or argv[i + 1].startswith("--")) else a
            for i, a in enumerate(argv)]
    argv = [REPEATED.get(a, a) for a in argv]
    return [f"{REPEATED[a.partition('=')[0]]}={a.partition('=')[2]}" if a.partition("=")[0] in REPEATED else a
            for a in argv]


def config_mistake(report: str) -> str:
    """jsonargparse's report of a config mistake in one line: the key (or the class whose ``init_args`` it refused) and
    the reason (the deepest error of a union)."""
    key = re.search(r'[Kk]ey "([^"]+)"', report)
    lines = [line.strip() for line in report.splitlines()]
    errors = [line.removeprefix("- ") for line in lines if line.startswith("- ") and "Expected a <class" not in line]
    reason = errors[-1] if errors else lines[0]
    if reason.endswith(":"):  # its detail is on the next line
        reason = f"{reason} {lines[lines.index(next(l for l in lines if l.endswith(reason))) + 1]}"
    reason = re.sub(r"Expected a dot import path string: (\S+)", r"cannot import class_path \1; give module.Class of an "
                    r"importable class, or a library name", reason)
    owner = re.search(r"class_path='([^']+)'", report)
    where = f"config key {key.group(1)!r}: " if key else f"config class_path {owner.group(1)}: " if owner else ""
    return f"{where}{reason}"


def diagnose_parser(prog: str = "torchpaml diagnose", skip: set[str] | None = None) -> ArgumentParser:
    """The parser of :func:`diagnose_command`'s arguments (``skip``: those left out), ``--config`` included."""
    parser = ArgumentParser(prog=prog, description=__doc__)
    parser.add_argument("--config", action=ActionConfigFile, help="YAML file with the arguments below")
    parser.add_function_arguments(diagnose_command, skip=skip)
    return parser


def run_diagnose(argv: list[str], prog: str = "torchpaml diagnose") -> dict:
    """Parse ``argv`` (after ``diagnose``) with jsonargparse, ``--config`` included, and run :func:`diagnose_command`."""
    parser = diagnose_parser(prog)
    parser.exit_on_error = False  # a config mistake is summarised in one line (config_mistake)
    try:
        config = parser.parse_args(normalise_arguments(argv))
    except ArgumentError as error:
        raise ConfigurationError(config_mistake(str(error))) from None
    try:
        config = parser.instantiate(config)
    except ValueError as error:  # a class that refuses its init_args (jsonargparse reports it as a union mismatch)
        raise ConfigurationError(config_mistake(str(error))) from None
    _beside_config(config, config.pop("config"), argv)
    with progress_lines(prog, enabled=not config["quiet"]):
        return diagnose_command(**config)


def _beside_config(config: dict, files: list | None, argv: list[str]) -> None:
    """The record paths (``data``, ``validation``) that a config file gives, relative to that file's folder, as
    LightningCLI's users expect; those given on the command line stay relative to the current folder."""
    for file in files or []:
        content = yaml.safe_load(Path(file.absolute).read_text()) or {}
        folder = Path(file.absolute).parent
        for key in RECORD_KEYS:
            if key in content and not any(a == f"--{key}" or a.startswith(f"--{key}=") for a in argv):
                given = config[key]
                config[key] = [str(folder / p) if not Path(p).is_absolute() else p for p in given] \
                    if isinstance(given, list) else str(folder / given) if not Path(given).is_absolute() else given
