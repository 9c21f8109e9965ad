"""Design sweeps: one design per point of a grid of requests, and the table check between neighbours.

A point runs as one call of ``run_point`` (module-level, picklable) on an ``Executor``: the supervised solver
pool, the calling process (``InlineExecutor``) or a Dask cluster (``runtime.dask.DaskExecutor``). It returns the
point's row (the numbers of the family endpoint's ``metrics``, ``sensitivity.band_5_percent`` and ``solver``) and
the design's command, which is all the table check needs: the sampled ``Result`` stays in the worker.

The table check, for each pair of neighbouring points (consecutive values along one axis, the other
coordinates equal): the percentage vibration V of each point's command on the other's plant, in the product's
definition (``optim.synthesis.nominal_percentage_vibration``: the residual at the neighbour's first mode over the
residual envelope of the neighbour's unshaped rigid reference; docs/api.md). The pair passes when both
stay <= the threshold. Refinement bisects a failing pair along its axis (the midpoint, the other coordinates
unchanged) and checks both halves, round after round, up to a budget of new points; rounds and the order of the
new points do not depend on which point finishes first, so the same sweep gives the same rows on any executor.

This module does no HTTP: ``prepare`` (a point's values -> its problem and options) is the caller's, and so is
the lines' JSON (a failed row carries the error, which the caller describes).
"""

from __future__ import annotations

import asyncio
import itertools
import math
import time
from collections.abc import AsyncIterator, Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter, PoolUnavailable
from optim.problem import Problem
from optim.registry import FAMILIES
from optim.results import Block
from optim.synthesis import Result, nominal_percentage_vibration, synthesize
from runtime.executor import Executor, PoolBusy, cancel_all

T = TypeVar("T")

RETRY_FIRST_S = 0.05  # a refused submission (pool busy or starting) is retried after this, doubling
RETRY_MAX_S = 1.0
MAX_UNAVAILABLE_RETRIES = 2
BISECT_RTOL = 1e-9  # an interval narrower than this (relative) is not bisected further

_warm: set[str] = set()  # the families whose solvers this process has built


# --- one point, in a worker --------------------------------------------------------------------


@dataclass(frozen=True)
class PointSolver(Block):
    status: str
    iterations: int
    solves: int


@dataclass(frozen=True)
class PointRow(Block):
    """The numbers of one point, named as in the family endpoint's answer (``metrics``, ``sensitivity``)."""

    duration_s: float
    settling_time_s: float | None
    percentage_vibration: float | None
    residual_amplitude: float
    residual_velocity_amplitude: float
    band_5_percent: tuple[float | None, float | None] | None
    limits_met: bool
    solver: PointSolver | None
    warnings: tuple[str, ...]
    elapsed_s: float


@dataclass(frozen=True)
class PointOutcome:
    """What a point's worker sends back: the row's numbers and the command the table check simulates."""

    row: PointRow
    command: PiecewiseCommand


@dataclass(frozen=True)
class PointDone:
    """A point done: its row, or its failure (the error and the context ``prepare`` gave, None if it failed there)."""

    index: int
    values: dict[str, float]  # axis path -> value
    between: tuple[int, int] | None  # the pair a refinement point bisects
    row: PointRow | None
    error: Exception | None = None
    context: Any = None


@dataclass(frozen=True)
class PairCheck(Block):
    """The table check of one pair of neighbours; passes is None where a point failed or V is undefined."""

    axis: str
    pair: tuple[int, int]
    values: tuple[float, float]
    a_at_b_percentage_vibration: float | None
    b_at_a_percentage_vibration: float | None
    worst_percentage_vibration: float | None
    passes: bool | None


@dataclass(frozen=True)
class SweepSummary(Block):
    points: int
    failed: int
    refined: int
    pairs: int
    pairs_failing: int
    pairs_unchecked: int
    interpolable: bool
    threshold_percent: float
    elapsed_s: float


Line = PointDone | PairCheck | SweepSummary


def run_point(family_name: str, problem: Problem, options: Any) -> PointOutcome:
    """Design one point through the family endpoint's pipeline; the row and the design's command only."""
    family = FAMILIES[family_name]
    if family_name not in _warm:  # a Dask worker builds the family's solvers on its first point; in the pool's
        family.warm_up(problem.solver)  # workers (warm since they started) this finds them in the caches
        _warm.add(family_name)
    started = time.perf_counter()
    result = synthesize(family, problem, options)
    return PointOutcome(point_row(result, time.perf_counter() - started), check_command(result))


def point_row(result: Result, elapsed_s: float) -> PointRow:
    """The numbers of one point, named as in the family endpoint's answer (``metrics``, ``sensitivity``)."""
    m = result.metrics
    solver = result.solver
    return PointRow(
        duration_s=m.command_end_s,
        settling_time_s=m.settling.time_s,
        percentage_vibration=result.percentage_vibration,
        residual_amplitude=m.residual_amplitude,
        residual_velocity_amplitude=m.residual_velocity_amplitude,
        band_5_percent=None if result.sensitivity is None else result.sensitivity.band_5_percent,
        limits_met=not result.limit_violations,
        solver=None if solver is None else PointSolver(solver.status, solver.iterations, solver.solves),
        warnings=result.warnings,
        elapsed_s=elapsed_s,
    )


def check_command(result: Result) -> PiecewiseCommand:
    """The command the check runs on a neighbour's plant: the design's exact one (a few breakpoints), else the
    sampled command the endpoint's own percentage vibration is computed on."""
    return result.design.command if result.design.command is not None else result.command


def cross_percentage_vibration(command: PiecewiseCommand, plant_problem: Problem) -> float | None:
    """V of ``command`` on the plant (and under the reference) of ``plant_problem``, %; None without a mode or
    where round-off would spoil it."""
    try:
        return nominal_percentage_vibration(plant_problem, command)
    except InvalidParameter:
        return None


# --- the grid -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Axis:
    """One axis: its request path, its values (strictly increasing), how to bisect it."""

    path: str
    values: tuple[float, ...]
    log_scale: bool = False
    integer: bool = False

    def midpoint(self, low: float, high: float) -> float | None:
        """The point between two values (geometric on a log axis, rounded down on an integer one); None when the
        interval cannot be split further."""
        if self.integer:
            mid: float = (int(low) + int(high)) // 2
            return mid if low < mid < high else None
        mid = math.sqrt(low * high) if self.log_scale else 0.5 * (low + high)
        if not (low < mid < high) or (high - low) <= BISECT_RTOL * max(abs(low), abs(high)):
            return None
        return mid


def grid_points(axes: Sequence[Axis]) -> list[tuple[float, ...]]:
    """The Cartesian product, the first axis varying slowest (``itertools.product``)."""
    return list(itertools.product(*(a.values for a in axes)))


def grid_pairs(shape: Sequence[int]) -> list[tuple[int, int, int]]:
    """(axis, a, b) for each pair of neighbouring grid points (flat indices in ``grid_points``' order)."""
    strides = [math.prod(shape[k + 1 :]) for k in range(len(shape))]
    pairs = []
    for flat, index in enumerate(itertools.product(*(range(n) for n in shape))):
        for k, n in enumerate(shape):
            if index[k] + 1 < n:
                pairs.append((k, flat, flat + strides[k]))
    return sorted(pairs, key=lambda p: (p[1], p[0]))


# --- the sweep ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Pair:
    axis: int
    a: int
    b: int


@dataclass
class _State:
    values: dict[int, tuple[float, ...]] = field(default_factory=dict)
    problems: dict[int, Problem] = field(default_factory=dict)
    commands: dict[int, PiecewiseCommand] = field(default_factory=dict)
    released: set[int] = field(default_factory=set)  # done, their commands dropped (``_release``)
    failed: set[int] = field(default_factory=set)
    checks: dict[Pair, bool | None] = field(default_factory=dict)
    leaves: list[Pair] = field(default_factory=list)


@dataclass(frozen=True)
class Prepared:
    """A point ready to run: its problem and options, and the caller's context for naming its failures (the
    validated request)."""

    problem: Problem
    options: Any
    context: Any = None


class _Failed(Exception):
    def __init__(self, error: Exception, context: Any) -> None:
        self.error, self.context = error, context
        super().__init__(str(error))


Prepare = Callable[[tuple[float, ...]], Prepared]


async def submit(executor: Executor, fn: Callable[..., T], *args: Any, deadline_s: float) -> T:
    """``executor.run``, resubmitted while the pool refuses it (``PoolBusy``: every worker busy and the queue full)
    for at most ``deadline_s`` of waiting: a sweep waits for room instead of failing. Any other ``PoolUnavailable``
    (workers starting, or the point's worker died) is retried ``MAX_UNAVAILABLE_RETRIES`` times, so that a point
    that kills its worker is reported, not run again and again."""
    delay = RETRY_FIRST_S
    waited = 0.0
    unavailable = 0
    while True:
        try:
            return await executor.run(fn, *args, deadline_s=deadline_s)
        except PoolUnavailable as exc:
            if not isinstance(exc, PoolBusy):
                unavailable += 1
            if waited >= deadline_s or unavailable > MAX_UNAVAILABLE_RETRIES:
                raise
            await asyncio.sleep(delay)
            waited += delay
            delay = min(RETRY_MAX_S, 2 * delay)


async def sweep(
    family_name: str,
    axes: Sequence[Axis],
    prepare: Prepare,
    executor: Executor,
    *,
    capacity: int,
    deadline_s: float,
    threshold_percent: float,
    refine: bool = False,
    max_refined_points: int = 0,
    max_points: int | None = None,
) -> AsyncIterator[Line]:
    """The sweep's lines, as they come: a ``row`` per point as it finishes, a ``check`` per neighbouring pair once
    both ends are done, a ``summary`` last. At most ``capacity`` points are in flight; leaving the generator (a
    client that went away) cancels the rest."""
    started = time.perf_counter()
    state = _State()
    budget = max_refined_points if refine else 0
    if max_points is not None:
        budget = max(0, min(budget, max_points - math.prod(len(a.values) for a in axes)))
    points = grid_points(axes)
    round_points: list[tuple[int, tuple[float, ...], Pair | None]] = [(i, v, None) for i, v in enumerate(points)]
    pending = [Pair(k, a, b) for k, a, b in grid_pairs([len(a.values) for a in axes])]
    refined = 0
    while round_points:
        for index, values, _ in round_points:
            state.values[index] = values
        async for line in _run_round(
            family_name,
            axes,
            round_points,
            pending,
            state,
            prepare,
            executor,
            capacity,
            deadline_s,
            threshold_percent,
            refined < budget,
        ):
            yield line
        state.leaves += pending
        failing = [p for p in pending if state.checks.get(p) is False]
        round_points, pending = [], []
        next_index = len(state.values)
        for pair in failing:
            if refined >= budget:
                break
            a, b = state.values[pair.a], state.values[pair.b]
            mid = axes[pair.axis].midpoint(a[pair.axis], b[pair.axis])
            if mid is None:
                continue
            values = tuple(mid if k == pair.axis else v for k, v in enumerate(a))
            index = next_index + len(round_points)
            round_points.append((index, values, pair))
            state.leaves.remove(pair)
            pending += [Pair(pair.axis, pair.a, index), Pair(pair.axis, index, pair.b)]
            refined += 1
        _release(state, pending, keep_failing=False)  # only the ends of the pairs still to check stay
    leaves = [state.checks.get(p) for p in state.leaves]
    yield SweepSummary(
        points=len(state.values),
        failed=len(state.failed),
        refined=refined,
        pairs=len(state.checks),
        pairs_failing=sum(1 for c in leaves if c is False),
        pairs_unchecked=sum(1 for c in leaves if c is None),
        interpolable=not state.failed and all(c is True for c in leaves),
        threshold_percent=threshold_percent,
        elapsed_s=time.perf_counter() - started,
    )


async def _run_round(
    family_name: str,
    axes: Sequence[Axis],
    round_points: list[tuple[int, tuple[float, ...], Pair | None]],
    pairs: list[Pair],
    state: _State,
    prepare: Prepare,
    executor: Executor,
    capacity: int,
    deadline_s: float,
    threshold_percent: float,
    keep_failing: bool,
) -> AsyncIterator[Line]:
    waiting = iter(round_points)
    running: dict[asyncio.Task[tuple[Problem, PointOutcome]], tuple[int, tuple[float, ...], Pair | None]] = {}
    open_pairs = list(pairs)

    async def one(values: tuple[float, ...]) -> tuple[Problem, PointOutcome]:
        prepared = await asyncio.to_thread(prepare, values)
        try:
            outcome = await submit(
                executor, run_point, family_name, prepared.problem, prepared.options, deadline_s=deadline_s
            )
        except Exception as exc:
            raise _Failed(exc, prepared.context) from None
        return prepared.problem, outcome

    def fill() -> None:
        while len(running) < max(1, capacity):
            item = next(waiting, None)
            if item is None:
                return
            running[asyncio.ensure_future(one(item[1]))] = item

    try:
        fill()
        while running:
            done, _ = await asyncio.wait(running, return_when=asyncio.FIRST_COMPLETED)
            for task in sorted(done, key=lambda t: running[t][0]):
                index, values, between = running.pop(task)
                at = {a.path: v for a, v in zip(axes, values, strict=True)}
                bisected = None if between is None else (between.a, between.b)
                exc = task.exception()
                if exc is None:
                    problem, outcome = task.result()
                    state.problems[index], state.commands[index] = problem, outcome.command
                    yield PointDone(index, at, bisected, outcome.row)
                else:
                    state.failed.add(index)
                    if not isinstance(exc, Exception):
                        raise exc
                    failure, context = (exc.error, exc.context) if isinstance(exc, _Failed) else (exc, None)
                    yield PointDone(index, at, bisected, None, failure, context)
                for pair in [p for p in open_pairs if _finished(p, state)]:
                    open_pairs.remove(pair)
                    # two simulations of a command (a sampled one may hold thousands of samples): off the loop
                    yield await asyncio.to_thread(_check, pair, axes, state, threshold_percent)
                _release(state, [*open_pairs, *pairs], keep_failing)
            fill()
    finally:
        await cancel_all(running)


def _release(state: _State, pairs: Sequence[Pair], keep_failing: bool) -> None:
    """Drop the commands no check needs any more: a point's command (up to VIBFREE_MAX_SAMPLES samples of a
    sampled design: 245 KiB for a default smoother point, so 1000 points held 245 MiB) is kept while a pair of
    ``pairs`` it ends is unchecked, or, with refinement to come (``keep_failing``), while a pair it ends fails
    (its midpoint is checked against it next round). The rest of the sweep then holds the points in flight and
    the unfinished neighbours along the axes, not every point."""
    needed = {i for p in pairs if p not in state.checks for i in (p.a, p.b)}
    if keep_failing:
        needed |= {i for p in pairs if state.checks.get(p) is False for i in (p.a, p.b)}
    for index in [i for i in state.commands if i not in needed]:
        del state.commands[index]
        state.released.add(index)


def _finished(pair: Pair, state: _State) -> bool:
    def done(i: int) -> bool:
        return i in state.commands or i in state.failed or i in state.released

    return done(pair.a) and done(pair.b)


def _check(pair: Pair, axes: Sequence[Axis], state: _State, threshold_percent: float) -> PairCheck:
    """The check line of one pair; passes is None where a point failed or V is undefined (no mode)."""
    a_at_b = b_at_a = None
    if pair.a in state.commands and pair.b in state.commands:
        a_at_b = cross_percentage_vibration(state.commands[pair.a], state.problems[pair.b])
        b_at_a = cross_percentage_vibration(state.commands[pair.b], state.problems[pair.a])
    worst = None if a_at_b is None or b_at_a is None else max(a_at_b, b_at_a)
    passes = None if worst is None else worst <= threshold_percent
    state.checks[pair] = passes
    return PairCheck(
        axis=axes[pair.axis].path,
        pair=(pair.a, pair.b),
        values=(state.values[pair.a][pair.axis], state.values[pair.b][pair.axis]),
        a_at_b_percentage_vibration=a_at_b,
        b_at_a_percentage_vibration=b_at_a,
        worst_percentage_vibration=worst,
        passes=passes,
    )
