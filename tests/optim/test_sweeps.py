"""Design sweeps (issue 15): the table check against the ZV shaper's known sensitivity, refinement, the grid's
neighbours, the engine's admission (a busy pool delays a point, never fails it), cancellation, and the same rows
on a Dask LocalCluster as in-process."""

from __future__ import annotations

import asyncio
import math
from typing import Any

import numpy as np
import pytest

from app.services.sweeps import line_json
from models.errors import InvalidParameter, PoolUnavailable
from models.plants import make_plant
from optim import sweeps
from optim.families.input_shaped.options import InputShapedOptions
from optim.problem import Problem
from runtime.dask import DaskExecutor
from runtime.executor import InlineExecutor, PoolBusy
from tests import aio

BASE_HZ = 10.0
# Undamped ZV shaper on a velocity step (no acceleration limit, so V is the classical ratio to the unshaped step):
# V(r) = |cos(pi r / 2)| with r = true / design frequency (Singer and Seering 1990; Singhose's "Command shaping for
# flexible systems", eq. for the two-impulse ZV). The 5 % edges: cos(pi r / 2) = 0.05.
R_LOW = 2 / math.pi * math.acos(0.05)  # 0.96817: a design used on a slower plant
R_HIGH = 2 - R_LOW  # 1.03183: on a faster plant (|cos| is symmetric about r = 1)
# A pair (f_a < f_b) passes when both designs stay <= 5 %: f_b / f_a <= R_HIGH (a on b) and f_a / f_b >= R_LOW
# (b on a), i.e. a spacing ratio q <= min(R_HIGH, 1 / R_LOW) = R_HIGH.
Q_EDGE = min(R_HIGH, 1 / R_LOW)


def zv_v(ratio: float) -> float:
    return 100 * abs(math.cos(math.pi * ratio / 2))


def zv_prepare(values: tuple[float, ...]) -> sweeps.Prepared:
    plant = make_plant("mode", natural_frequency_hz=values[0], damping_ratio=0.0)
    problem = Problem(plant=plant, target_velocity=1.0)
    return sweeps.Prepared(problem, InputShapedOptions(shaper="zv"))


def describe(exc: Exception, context: Any) -> dict[str, Any]:
    return {"type": type(exc).__name__, "detail": str(exc)}


def _json(line: sweeps.Line) -> dict[str, Any]:
    """The line as the service writes it (app.services.sweeps.line_json), a failure named by its exception."""
    return line_json(line, describe)


def frequency_axis(ratio: float, count: int) -> sweeps.Axis:
    return sweeps.Axis("plant.natural_frequency_hz", tuple(BASE_HZ * ratio**k for k in range(count)), log_scale=True)


def run(axes, prepare=zv_prepare, executor=None, **kwargs) -> list[dict[str, Any]]:
    async def collect() -> list[dict[str, Any]]:
        lines = sweeps.sweep(
            "input_shaped",
            axes,
            prepare,
            executor or InlineExecutor(),
            capacity=kwargs.pop("capacity", 1),
            deadline_s=30.0,
            threshold_percent=5.0,
            **kwargs,
        )
        return [_json(line) async for line in lines]

    return aio.run(collect())


def of(lines, kind):
    return [line for line in lines if line["line"] == kind]


def test_zv_table_check_flags_a_table_just_too_coarse_and_passes_one_just_fine_enough():
    coarse = run([frequency_axis(Q_EDGE * 1.01, 4)])
    fine = run([frequency_axis(Q_EDGE * 0.99, 4)])
    for lines, ratio in ((coarse, Q_EDGE * 1.01), (fine, Q_EDGE * 0.99)):
        checks = of(lines, "check")
        assert len(checks) == 3
        for check in checks:
            # the closed form above, at the pair's true ratio; 1e-6 %: the shaper's impulse times are exact to
            # round-off, so V agrees to about eps x the 1/omega^2 scale of the residual (far below 1e-6)
            assert check["a_at_b_percentage_vibration"] == pytest.approx(zv_v(ratio), abs=1e-6)
            assert check["b_at_a_percentage_vibration"] == pytest.approx(zv_v(1 / ratio), abs=1e-6)
    assert all(c["passes"] is False for c in of(coarse, "check"))
    assert all(c["passes"] is True for c in of(fine, "check"))
    assert of(coarse, "summary")[0]["interpolable"] is False
    assert of(fine, "summary")[0]["interpolable"] is True


def test_refinement_bisects_the_failing_pairs_and_then_passes():
    # spacing q = 1.05 > Q_EDGE fails; one geometric bisection gives sqrt(1.05) = 1.0247 < Q_EDGE: passes
    axis = frequency_axis(1.05, 3)
    lines = run([axis], refine=True, max_refined_points=10)
    rows = of(lines, "row")
    added = [r for r in rows if r["between"] is not None]
    assert [r["between"] for r in added] == [[0, 1], [1, 2]]
    for row in added:
        a, b = (axis.values[i] for i in row["between"])
        assert row["values"]["plant.natural_frequency_hz"] == pytest.approx(math.sqrt(a * b), rel=1e-15)
    final = of(lines, "check")[2:]  # the two original pairs fail, then the four halves
    assert [c["pair"] for c in final] == [[0, 3], [3, 1], [1, 4], [4, 2]]
    assert all(c["passes"] for c in final)
    summary = of(lines, "summary")[0]
    assert (summary["points"], summary["refined"], summary["pairs_failing"], summary["interpolable"]) == (5, 2, 0, True)


def test_refinement_stops_at_its_budget_and_says_the_table_still_fails():
    lines = run([frequency_axis(1.2, 3)], refine=True, max_refined_points=3)
    summary = of(lines, "summary")[0]
    assert summary["refined"] == 3
    assert summary["pairs_failing"] >= 1 and summary["interpolable"] is False


def test_grid_pairs_are_the_neighbours_along_each_axis():
    shape = (3, 2, 2)
    points = list(np.ndindex(*shape))  # C order: the first axis varies slowest, as itertools.product
    expected = {
        (k, i, j)
        for i, p in enumerate(points)
        for j, q in enumerate(points)
        for k in range(3)
        if q[k] == p[k] + 1 and all(q[m] == p[m] for m in range(3) if m != k)
    }
    assert set(sweeps.grid_pairs(shape)) == expected
    assert len(sweeps.grid_pairs(shape)) == 2 * 2 * 2 + 3 * 1 * 2 + 3 * 2 * 1


def test_midpoints_linear_log_and_integer():
    assert sweeps.Axis("x", (1.0, 4.0)).midpoint(1.0, 4.0) == 2.5
    assert sweeps.Axis("x", (1.0, 4.0), log_scale=True).midpoint(1.0, 4.0) == 2.0
    assert sweeps.Axis("n", (1, 4), integer=True).midpoint(1, 4) == 2
    assert sweeps.Axis("n", (1, 2), integer=True).midpoint(1, 2) is None  # nothing between neighbouring integers
    assert sweeps.Axis("x", (1.0, 1.0 + 1e-12)).midpoint(1.0, 1.0 + 1e-12) is None


class BusyThenInline:
    """Refuses each point's first two submissions as a full pool does, then runs it."""

    def __init__(self) -> None:
        self.refusals: dict[Any, int] = {}

    async def run(self, fn, *args, deadline_s):
        key = id(args[1])
        self.refusals[key] = self.refusals.get(key, 0) + 1
        if self.refusals[key] <= 2:
            raise PoolBusy("every solver worker is busy", retry_after_s=1)
        return fn(*args)


def test_a_busy_pool_delays_points_and_never_fails_them():
    executor = BusyThenInline()
    lines = run([frequency_axis(1.02, 3)], executor=executor, capacity=3)
    assert all(r["ok"] for r in of(lines, "row"))
    assert sorted(executor.refusals.values()) == [3, 3, 3]


class DyingWorker:
    """Every submission meets a worker that stopped unexpectedly (a point that crashes its worker)."""

    def __init__(self) -> None:
        self.calls = 0

    async def run(self, fn, *args, deadline_s):
        self.calls += 1
        raise PoolUnavailable("a solver worker stopped unexpectedly (exit code -11); it is being replaced")


def test_a_point_whose_worker_dies_is_retried_twice_then_reported():
    executor = DyingWorker()
    lines = run([frequency_axis(1.02, 1)], executor=executor)
    assert executor.calls == 1 + sweeps.MAX_UNAVAILABLE_RETRIES
    (row,) = of(lines, "row")
    assert row["ok"] is False and "stopped unexpectedly" in row["problem"]["detail"]


def test_an_invalid_point_is_a_row_with_its_reason_and_the_sweep_goes_on():
    def prepare(values):
        if values[0] > 10.5:
            raise InvalidParameter("plant.natural_frequency_hz", values[0], "too fast for this test")
        return zv_prepare(values)

    lines = run([frequency_axis(1.02, 4)], prepare=prepare)
    rows = sorted(of(lines, "row"), key=lambda r: r["index"])
    assert [r["ok"] for r in rows] == [True, True, True, False]
    assert rows[3]["problem"]["type"] == "InvalidParameter" and "too fast" in rows[3]["problem"]["detail"]
    assert of(lines, "check")[-1]["passes"] is None
    summary = of(lines, "summary")[0]
    assert (summary["failed"], summary["pairs_unchecked"], summary["interpolable"]) == (1, 1, False)


class Slow:
    """The first point is quick, every other one takes seconds (an asyncio sleep, as the pool's await does); counts
    what was started and cancelled."""

    def __init__(self) -> None:
        self.started = 0
        self.cancelled = 0

    async def run(self, fn, *args, deadline_s):
        self.started += 1
        try:
            await asyncio.sleep(0.05 if self.started == 1 else 5.0)
        except asyncio.CancelledError:
            self.cancelled += 1
            raise
        return fn(*args)


def test_leaving_the_stream_cancels_the_points_in_flight_and_starts_no_more():
    executor = Slow()

    async def first_row() -> dict[str, Any]:
        lines = sweeps.sweep(
            "input_shaped",
            [frequency_axis(1.02, 20)],
            zv_prepare,
            executor,
            capacity=4,
            deadline_s=30.0,
            threshold_percent=5.0,
        )
        try:
            return _json(await anext(lines))
        finally:
            await lines.aclose()  # what Starlette does when the client goes away

    assert aio.run(first_row())["index"] == 0
    assert executor.started == 4  # the capacity, and none after the consumer left
    assert executor.cancelled == 3  # the three still running


def test_the_same_sweep_on_a_local_dask_cluster_gives_identical_rows():
    distributed = pytest.importorskip("distributed")
    axes = [frequency_axis(1.05, 4)]
    local = run(axes, refine=True, max_refined_points=4)

    async def on_cluster(address: str) -> list[dict[str, Any]]:
        async with DaskExecutor.connect(address) as dask:
            capacity = 2 * await dask.capacity()
            lines = sweeps.sweep(
                "input_shaped",
                axes,
                zv_prepare,
                dask,
                capacity=capacity,
                deadline_s=60.0,
                threshold_percent=5.0,
                refine=True,
                max_refined_points=4,
            )
            return [_json(line) async for line in lines]

    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
    ) as cluster:
        remote = aio.run(on_cluster(cluster.scheduler_address))

    def numbers(lines):
        rows = sorted(of(lines, "row"), key=lambda r: r["index"])
        return [{k: v for k, v in r.items() if k != "elapsed_s"} for r in rows], sorted(
            of(lines, "check"), key=lambda c: c["pair"]
        )

    assert numbers(remote) == numbers(local)  # exact: the same code on the same inputs, only the process differs
    assert of(remote, "summary")[0]["refined"] == of(local, "summary")[0]["refined"] == 3


def test_a_sweep_holds_the_commands_of_its_unfinished_neighbours_only(monkeypatch):
    # A point's command (a sampled design's: up to VIBFREE_MAX_SAMPLES samples, 245 KiB for a default smoother
    # point) was held until the sweep ended: 1000 points, 245 MiB in the HTTP process. It is dropped once every pair
    # it ends is checked: 12 points run one at a time along one axis hold at most 2 commands (a point waits for
    # its right neighbour), and the checks are those of the closed form (a ZV shaper off by the grid's ratio).
    most = 0

    class Counting(dict):
        def __setitem__(self, key, value):
            nonlocal most
            super().__setitem__(key, value)
            most = max(most, len(self))

    state = sweeps._State
    monkeypatch.setattr(sweeps, "_State", lambda: state(commands=Counting()))
    ratio = Q_EDGE * 0.99
    lines = run([frequency_axis(ratio, 12)])
    assert len(of(lines, "row")) == 12 and len(of(lines, "check")) == 11
    assert all(check["passes"] for check in of(lines, "check"))
    assert 1 <= most <= 2
