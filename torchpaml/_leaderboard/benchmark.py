r"""A measured benchmark's protocol as one frozen value: its data, splits, metric and unit, where a free run starts,
the published figures it is set beside, and the goal.

The metric is one function for every benchmark (:meth:`Benchmark.score`): the RMSE of the first output, in the
benchmark's unit (``scale`` times the data's), of a free run of a fitted model on a test record,

$$ \mathrm{RMSE} = \text{scale} \cdot \sqrt{\tfrac{1}{N - n_0} \textstyle\sum_{k \ge n_0} (y_k - \hat y_k)^2}, $$

from the state ``start`` says, over the samples after the first $n_0$ = ``init_window``; a split in
``steady_state`` is one period of a periodic input, applied twice from rest and scored on the second
(:func:`~torchpaml._leaderboard.protocols.periodic_twice`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import torch

from torchpaml._data import Record
from torchpaml._data.simulation import record_states, simulate_record
from torchpaml._diagnostics.results import ModelScore
from torchpaml._fit.initial_state import Estimate, InitialState
from torchpaml._fit.physics_fit import estimate_initial_state
from torchpaml._leaderboard.protocols import periodic_twice
from torchpaml._errors import ConfigurationError
from torchpaml._physics.base import AbstractPhysics
from torchpaml._physics.effect import AbstractEffect
from torchpaml._simulate.solvers import Auto, Solver

__all__ = ["Benchmark", "Published"]


@dataclass(frozen=True)
class Published:
    """A published figure on the benchmark's headline split, quoted from its source (not computed here);
    ``caveat``: how its protocol differs from an honest one (e.g. a model selected on the test record), shown beside
    it."""

    figure: str
    model: str
    source: str
    kind: Literal["black box", "grey box"]
    caveat: str = ""


@dataclass(frozen=True)
class Benchmark:
    """One measured benchmark (module docstring).

    Attributes:
        name: its name in the registry and in ``<name>.json``.
        title: its name in prose.
        folder: its data folder under ``shared/data``.
        train: the training record's file stem; its last ``validation_share`` is held out for validation.
        tests: the test records' file stems, touched only to score.
        metric: what the figure measures, in words.
        unit: the figure's unit; ``scale``: that unit per unit of the data (1000: mV from V).
        init_window: the samples of a test record that may set the model's state, left out of the score.
        start: where a free run on a test record starts: ``"window"`` (the state that best explains the first
            ``init_window`` samples), ``"rest"``, or ``"train"`` (the training record's estimated initial state, where
            the benchmark's document says both records start from the same state).
        goal: the leaderboard's goal on ``goal_split``, in ``unit``.
        published: the published figures the leaderboard sets ours beside.
        experiment: the script that runs the protocol, relative to the repository, and ``arguments``, what the
            leaderboard passes it beside ``--out``; ``None``: the registry's own protocol runs it
            (:func:`~torchpaml._leaderboard.runner.run_benchmark`), from ``model``, ``candidates`` and ``initial_state``:
            then the benchmark is its entry file and its data.
        model: builds the physics the diagnosis starts from, given the training part (a start from its frequency
            response, say); for the registry's own protocol.
        candidates: the effects the diagnosis ranks (default: :func:`~torchpaml.default_effects`).
        initial_state: each record's initial state in the fits of the registry's protocol: ``Estimate()`` (the
            default: the validation part starts inside the training record, not at rest) or ``Rest()``.
        steady_state: the splits scored in their periodic steady state.
        hold: how the input moved between samples (``None``: the file's metadata, else ``foh``).
        velocity: the model's state that is the output's rate, scored beside the output (module docstring);
            ``None``: none.
    """

    name: str
    title: str
    folder: str
    train: str
    tests: tuple[str, ...]
    metric: str
    unit: str
    goal_split: str
    goal: float
    published: tuple[Published, ...]
    experiment: str | None = None
    scale: float = 1.0
    init_window: int = 0
    start: Literal["window", "rest", "train"] = "window"
    validation_share: float = 0.2
    steady_state: tuple[str, ...] = ()
    arguments: tuple[str, ...] = ()
    hold: str | None = None
    velocity: str | None = None
    model: Callable[[Record], AbstractPhysics] | None = None
    candidates: Callable[[], list[AbstractEffect]] | None = None
    initial_state: InitialState = field(default_factory=Estimate)

    def __post_init__(self):
        if (self.experiment is None) == (self.model is None):
            raise ValueError(f"{self.name}: give either an experiment script or a model for the registry's protocol "
                             "(Benchmark(model=lambda train: physics)), not both")
        if self.goal_split not in self.tests or not set(self.steady_state) <= set(self.tests):
            raise ValueError(f"{self.name}: the goal's split and the steady-state splits must be test splits "
                             f"{self.tests}")

    def split(self, record: Record) -> tuple[Record, Record]:
        """The training record's first ``1 - validation_share`` for training, the rest for validation."""
        cut = int(round((1 - self.validation_share) * len(record.t)))
        return record.window(0, cut, "train"), record.window(cut, None, "validation")

    def protocol(self) -> dict:
        """The ``protocol`` block of ``<name>.json``."""
        return {"train": f"{self.train} (its last {100 * self.validation_share:.0f} % for validation)",
                "test": list(self.tests), "init_window": self.init_window, "metric": self.metric, "unit": self.unit}

    def prepared(self, record: Record) -> Record:
        """``record`` as it is simulated for its score: twice over where it is a steady-state split."""
        return periodic_twice(record) if record.name in self.steady_state else record

    def start_of(self, model, record: Record, solver: Solver | None = None,
                 train_state: torch.Tensor | None = None) -> torch.Tensor | None:
        """The state a free run of the fitted ``model`` (its fit's ``solver``) on the prepared ``record`` starts from
        (``start``; ``train_state``: the training record's estimated initial state, for ``"train"``)."""
        if self.start == "rest" or record.name in self.steady_state:
            return None
        if self.start == "train":
            if train_state is None:
                raise ConfigurationError(f"{self.name} starts a test run from the training record's estimated "
                                         "initial state; give it (train_state=)")
            return train_state
        return estimate_initial_state(model, record, self.init_window, solver=Auto(start=solver))

    def metric_of(self, record: Record, y_model: torch.Tensor) -> float:
        """The figure of the model output ``y_model`` (time, n_y) on the prepared ``record``."""
        return self._rms(record, (record.y - y_model)[:, 0])

    def _rms(self, record: Record, error: torch.Tensor) -> float:
        """``scale`` times the RMS of ``error`` (time,) over the samples of the prepared ``record`` that are scored."""
        first = len(record.t) // 2 if record.name in self.steady_state else self.init_window
        return self.scale * float(error[first:].square().mean().sqrt())

    def score(self, model, record: Record, *, solver: Solver | None = None,
              train_state: torch.Tensor | None = None) -> float:
        """The figure of the fitted ``model`` (simulated by its fit's ``solver``) on the test ``record``."""
        prepared = self.prepared(record)
        with torch.no_grad():
            y = simulate_record(model, prepared, self.start_of(model, prepared, solver, train_state), solver=solver)[0]
        return self.metric_of(prepared, y)

    def unit_of(self, key: str) -> str:
        """The unit of a figure keyed ``key`` in a row's ``rmse``: ``unit``, or ``unit``/s for ``<split>_velocity``."""
        return f"{self.unit}/s" if key.endswith("_velocity") else self.unit

    def velocity_score(self, model, record: Record, *, solver: Solver | None = None,
                       train_state: torch.Tensor | None = None) -> float:
        r"""The RMSE, in ``unit``/s, of the state :attr:`velocity` of the fitted ``model``'s free run on the test
        ``record`` (started as :meth:`score` starts it) against the central differences of the measured output,
        $\dot y_k \approx (y_{k+1} - y_{k-1}) / (t_{k+1} - t_{k-1})$, over the samples :meth:`score` scores."""
        if self.velocity is None:
            raise ConfigurationError(f"{self.name} scores no velocity; name the state (Benchmark(velocity=...))")
        prepared = self.prepared(record)
        with torch.no_grad():
            states = record_states(model, prepared, self.start_of(model, prepared, solver, train_state), solver)
        measured = torch.gradient(prepared.y[:, 0], spacing=(prepared.t,))[0]
        velocity = states[:, model.state_names.index(self.velocity)]
        return self._rms(prepared, measured - velocity)

    def scores(self, step: ModelScore, tests: dict[str, Record]) -> dict[str, float]:
        """:meth:`scores_of` a scored model: its model, solver and training records' initial states."""
        state = step.train_states[0] if step.train_states else None
        return self.scores_of(step.model, tests, solver=step.solver, train_state=state)

    def scores_of(self, model, tests: dict[str, Record], *, solver: Solver | None = None,
                  train_state: torch.Tensor | None = None) -> dict[str, float]:
        """:meth:`score` of the fitted ``model`` on every test record, by split, and where :attr:`velocity` names a
        state, :meth:`velocity_score` as ``<split>_velocity``."""
        figures = {name: self.score(model, record, solver=solver, train_state=train_state)
                   for name, record in tests.items()}
        if self.velocity is not None:
            figures |= {f"{name}_velocity": self.velocity_score(model, record, solver=solver, train_state=train_state)
                        for name, record in tests.items()}
        return figures
