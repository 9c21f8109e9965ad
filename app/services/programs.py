"""The programs use case: a machine program's moves designed (in parallel: each starts from rest at a stop), laid
end to end and checked (optim.programs), compared with the recipes, and presented as JSON, NDJSON progress or
a CSV cam table with one column per axis. The route (app.routers.programs), the Python API and the CLI call it.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator
from typing import Any

import anyio.to_thread
import numpy as np
import orjson

from app import problems
from app.presenters import present
from app.responses import csv_rows
from app.schemas.programs import ProgramIn
from app.services.sweeps import capacity_of
from app.settings import Settings
from models.errors import DomainError
from optim import sweeps as engine
from optim.programs import Program, ProgramResult, assemble, check_program
from optim.programs.compare import RecipeRow, compare
from optim.programs.moves import MoveDesign
from optim.programs.run import MoveOutcome, design_one, heaviest_first
from optim.programs.varying import VaryingFit
from optim.tables import uniform_times
from runtime.executor import Executor, InlineExecutor, cancel_all

Designed = tuple[MoveDesign, VaryingFit | None]


async def program_of(body: ProgramIn, settings: Settings, pool: Executor) -> Program:
    """The checked core program (a 422 naming the field otherwise); off the event loop in a server."""

    def build() -> Program:
        program = body.to_program(settings)
        check_program(program)
        return program

    return build() if isinstance(pool, InlineExecutor) else await anyio.to_thread.run_sync(build)


async def designed_moves(
    program: Program, executor: Executor, settings: Settings, capacity: int | None = None
) -> AsyncIterator[tuple[int, Designed, float]]:
    """Each move's design as it finishes (move, design, seconds): on the pool, at most ``capacity`` in flight (one
    running and one queued per worker: ``capacity_of``); a full pool delays a move, never fails it."""
    limit = asyncio.Semaphore(capacity or capacity_of(executor))

    async def one(k: int) -> tuple[int, Designed, float]:
        async with limit:
            started = time.perf_counter()
            done = await engine.submit(executor, design_one, program, k, deadline_s=settings.solve_deadline_s)
            return k, done, time.perf_counter() - started

    tasks = [asyncio.ensure_future(one(k)) for k in heaviest_first(program)]  # (the semaphore serves them in turn)
    try:
        for next_done in asyncio.as_completed(tasks):
            yield await next_done
    finally:
        await cancel_all(tasks)


def finish(
    program: Program, designed: list[Designed], with_comparison: bool
) -> tuple[ProgramResult, tuple[RecipeRow, ...]]:
    """The cycle and its checks, and the recipes' rows (module-level: a worker runs it)."""
    result = assemble(program, designed)
    return result, compare(program, result.cycle_time_s) if with_comparison else ()


async def answer(
    body: ProgramIn, settings: Settings, pool: Executor, capacity: int | None = None, assembler: Executor | None = None
) -> tuple[dict[str, Any], ProgramResult]:
    """The whole answer (JSON), and the result it was made from (for the CSV); the moves designed on ``pool`` (the
    solver pool, a Dask cluster, or here), ``capacity`` at a time (``capacity_of``), then the cycle's simulation on
    ``assembler`` (default ``pool``: the true plant's integration is Python-heavy, not for the HTTP process; the
    Python API's own process assembles, where a worker's round trip cost 0.08 s of bench/programs.py's 20 moves
    for 0.02 s of work)."""
    program = await program_of(body, settings, pool)
    found: dict[int, Designed] = {}
    async for k, done, _ in designed_moves(program, pool, settings, capacity):
        found[k] = done
    designed = [found[k] for k in range(len(program.moves))]
    result, rows = await engine.submit(
        assembler or pool, finish, program, designed, body.compare, deadline_s=settings.solve_deadline_s
    )
    return program_json(result, rows), result


async def progress(
    body: ProgramIn, program: Program, settings: Settings, pool: Executor, capacity: int | None = None
) -> AsyncIterator[dict[str, Any]]:
    """NDJSON lines for a checked program (``program_of``, before the answer starts): a ``move`` line per move as
    its design finishes, then the ``program`` line (the answer); a move without a design ends the lines with a
    ``problem`` line (the problem+json the JSON answer would be)."""
    try:
        async for line in _progress(body, program, settings, pool, capacity):
            yield line
    except DomainError as exc:
        yield {"line": "problem", **orjson.loads(problems.domain_problem(exc).body)}


async def _progress(
    body: ProgramIn, program: Program, settings: Settings, pool: Executor, capacity: int | None
) -> AsyncIterator[dict[str, Any]]:
    found: dict[int, Designed] = {}
    async for k, done, seconds in designed_moves(program, pool, settings, capacity):
        found[k] = done
        design, fit = done
        yield {
            "line": "move",
            "index": k,
            "done": len(found),
            "of": len(program.moves),
            "duration_s": design.duration_s,
            "varying": None if fit is None else present(fit),
            "elapsed_s": seconds,
        }
    designed = [found[k] for k in range(len(program.moves))]
    result, rows = await engine.submit(
        pool, finish, program, designed, body.compare, deadline_s=settings.solve_deadline_s
    )
    yield {"line": "program", **program_json(result, rows)}


# --- the answer's shape ----------------------------------------------------------------------------


def program_json(result: ProgramResult, comparison: tuple[RecipeRow, ...]) -> dict[str, Any]:
    program = result.program
    return {
        "cycle_time_s": result.cycle_time_s,
        "moves": [_move_json(program, k, m) for k, m in enumerate(result.moves)],
        "axes": {
            a.name: {
                "profile": {
                    "time_s": a.time_s,
                    **{name: a.profile[m] for m, name in enumerate(("position", "velocity", "acceleration", "jerk"))},
                },
                "load": {"time_s": a.time_s, "position": a.load[0], "velocity": a.load[1], "acceleration": a.load[2]},
                "stop_residual_method": a.method,
            }
            for a in result.axes
        },
        "comparison": [present(row) for row in comparison],
        "warnings": list(result.warnings),
    }


def _move_json(program: Program, k: int, outcome: MoveOutcome) -> dict[str, Any]:
    design = outcome.design
    move = program.moves[k]
    axes = {}
    for axis_move, axis_outcome in zip(design.axes, outcome.axes, strict=True):
        effective = None
        if axis_move.effective:
            mode = axis_move.plant.modes()[0]
            effective = {"natural_frequency_hz": mode.natural_frequency_hz, "damping_ratio": mode.damping_ratio}
        axes[axis_move.axis] = {
            "design": None if axis_move.summary is None else present(axis_move.summary),
            "metrics": None if axis_outcome.metrics is None else present(axis_outcome.metrics),
            "solver": None if axis_move.solver is None else present(axis_move.solver),
            "stop_residual_amplitude": axis_outcome.stop_residual_amplitude,
            "stop_residual_fraction": axis_outcome.stop_residual_fraction,
            "settling_time_s": axis_outcome.settling_time_s,
            "band_hz": None if axis_move.band_hz is None else list(axis_move.band_hz),
            "effective_mode": effective,
            "stretched_from_s": axis_move.stretched_from_s,
        }
    return {
        "index": k,
        "start_s": outcome.start_s,
        "duration_s": design.duration_s,
        "dwell_s": move.dwell_s,
        "settling_time_s": outcome.settling_time_s,
        "coordination": move.coordination,
        "still_at_stop": move.still_at_stop,
        "path": None if design.path is None else present(design.path),
        "varying": None if outcome.varying is None else present(outcome.varying),
        "axes": axes,
    }


def cam_table(result: ProgramResult) -> tuple[list[str], np.ndarray, float]:
    """The CSV's columns (time_s, then one per axis: its motor position), its rows at t_k = k * period exactly
    (each axis's exact command evaluated there), and the period (sample_period_s, or the answer's)."""
    axes = result.axes
    period = axes[0].period_s
    horizon = float(axes[0].time_s[-1])
    t = uniform_times(period, horizon)
    columns = [t, *(a.command.evaluate_at_instants(t, 1)[0] for a in axes)]
    values = np.column_stack(columns)
    values[values == 0.0] = 0.0
    return ["time_s", *(a.name for a in axes)], values, period


def cam_text(result: ProgramResult) -> str:
    """The CSV of ``format=csv``: a comment line (what the table is), the header, one row per instant."""
    columns, values, period = cam_table(result)
    head = (
        f"# machine program: {len(result.moves)} moves, cycle_time_s {result.cycle_time_s!r}; positions in each "
        f"axis's motor units; sample_period_s {period!r}, time_s = k * sample_period_s\n" + ",".join(columns) + "\n"
    )
    return head + csv_rows(values).decode()
