"""The input-shaping family (optim.families.input_shaped.family): automatic baseline, cruise, candidates, torque."""

from __future__ import annotations

import numpy as np
import pytest

from models.errors import Infeasible
from models.plants import example_plants, make_plant
from optim.registry import FAMILIES  # before the families' modules: the registry imports them

# isort: split
from optim.families.input_shaped.options import InputShapedOptions
from optim.families.input_shaped.shapers import CATALOGUE_NAMES
from optim.problem import Limits, Problem
from optim.synthesis import synthesize

PLANT = example_plants()["chatlatanagulchai_eq3"]
FAMILY = FAMILIES["input_shaped"]


# ------------------------------------------------------------------------------------------
# The family: automatic baseline, cruise within max_velocity, compare's candidates


def _design(problem: Problem, **options):
    """The family's pipeline answer for these options (the endpoint's numbers)."""
    return synthesize(FAMILY, problem, InputShapedOptions(**options))


@pytest.mark.parametrize("shaper", ["zv", "mzv", "zvd", "zvdd", "ei", "2hump_ei", "3hump_ei"])
def test_cruise_never_exceeds_max_velocity_and_every_limit_holds(shaper):
    # Each catalogue shaper on a 5 Hz mode, 0.2 m at a = 20, with max_velocity below the free fastest
    # cruise (it binds: the cruise is max_velocity) and above it (the cruise is the free optimum).
    plant = make_plant(kind="mode", natural_frequency_hz=5.0, damping_ratio=0.05)
    free = None
    for top in (None, 0.5, 10.0):
        problem = Problem(plant, displacement=0.2, limits=Limits(max_velocity=top, max_acceleration=20.0))
        result = _design(problem, shaper=shaper)
        m, cruise = result.metrics, abs(result.summary.baseline.velocity)
        free = cruise if top is None else free
        if top is not None:
            assert cruise == pytest.approx(min(top, free), rel=1e-12)
            assert m.peak_velocity <= top * (1 + 1e-12)
        assert m.peak_velocity <= cruise * (1 + 1e-12)  # positive impulses summing to 1
        assert m.peak_acceleration <= 20.0 * (1 + 1e-12)
        assert not result.limit_violations
        assert result.command.derivative(0)[-1] == pytest.approx(0.2, rel=1e-12)
        assert result.summary.passes_limiter_unchanged is True


def _end(problem: Problem, baseline: str, steps: int = 2) -> float | None:
    """The shaped command's end with this baseline, or None where it is refused or breaks the limit."""
    try:
        result = _design(problem, baseline=baseline, baseline_steps=steps)
    except Infeasible:
        return None
    return result.summary.duration_s if result.summary.passes_limiter_unchanged else None


@pytest.mark.parametrize("limit", [0.2, 0.1, 0.08, 0.05])
@pytest.mark.parametrize("move", [{"target_velocity": 1.0}, {"displacement": 10.0}])
def test_auto_is_the_fastest_baseline_that_meets_the_limit(limit, move):
    # ZVD on the paper's plant: the modified baseline fits for a >= 0.0909 (Sec. 4, PAPER-NOTES), not
    # below. auto ends no later than any explicit baseline whose shaped command meets the limit
    # (modified where it fits, multi_step with 1, 2 or 3 steps), passes the drive unchanged, and cancels
    # the mode (exact shaper, exact simulation: round-off).
    problem = Problem(PLANT, **move, limits=Limits(max_acceleration=limit))
    auto = _design(problem)
    ends = [_end(problem, "modified")] + [_end(problem, "multi_step", steps) for steps in (1, 2, 3)]
    assert auto.summary.duration_s <= min(e for e in ends if e is not None) * (1 + 1e-12)
    assert auto.summary.passes_limiter_unchanged is True
    if "target_velocity" in move:  # a rest-to-rest move may cruise slower so that the modified ramp fits
        assert (auto.summary.baseline.kind == "modified") == (limit >= 0.0909)
    assert auto.summary.baseline.requested == "auto" and "auto:" in auto.summary.baseline.choice
    residual = auto.metrics.residual_amplitude if "displacement" in move else auto.metrics.residual_velocity_amplitude
    assert residual < 1e-12


def test_explicit_baselines_keep_their_behaviour():
    # modified still refuses where its ramps would overlap (a rest-to-velocity move cannot slow down),
    # and the step baseline is still the plain staircase the drive distorts.
    problem = Problem(PLANT, target_velocity=1.0, limits=Limits(max_acceleration=0.05))
    with pytest.raises(Infeasible) as info:
        _design(problem, baseline="modified")
    assert "no-overlap" in info.value.reason
    step = _design(problem, baseline="step")
    assert step.summary.baseline.kind == "step" and step.summary.passes_limiter_unchanged is False


def test_compare_candidates_are_one_group_per_shaper_with_the_automatic_baseline():
    problem = Problem(PLANT, displacement=1.0, limits=Limits(max_acceleration=0.1))
    candidates = FAMILY.candidates(problem)
    assert [c.label for c in candidates] == [
        "input_shaped/zv",
        "input_shaped/mzv",
        "input_shaped/zvd",
        "input_shaped/ei",
    ]
    assert len({c.group for c in candidates}) == 4
    assert {c.options.baseline for c in candidates} == {"auto"}
    # Every shaper of the rows is in the catalogue, and the default is one design, ZVD with auto.
    assert {c.options.shaper for c in candidates} <= set(CATALOGUE_NAMES)
    assert FAMILY.default_options(problem) == InputShapedOptions(shaper="zvd", baseline="auto")


@pytest.mark.parametrize("shaper", ["mzv", "zvd", "ei"])
def test_motor_torque_stays_within_its_limit(shaper):
    # Cusimano's 8 Hz two-inertia plant to 150 rad/s with 10 N m: M / (J_M + J_L) = 1000 rad/s^2 bounds the
    # inertial torque only; at that limit the shaft adds up to 22 % (measured 12.2 N m for MZV). The family
    # lowers the acceleration limit until the simulated peak fits, and says so.
    plant = example_plants()["cusimano_8hz_equal_inertia"]
    problem = Problem(plant, target_velocity=150.0, limits=Limits(max_torque_nm=10.0))
    result = _design(problem, shaper=shaper)
    assert result.metrics.peak_motor_torque_nm <= 10.0 * (1 + 1e-9) and not result.limit_violations
    assert result.summary.acceleration_limit < 10.0 / 0.01
    assert any("lowered" in w for w in result.warnings)
    assert result.summary.passes_limiter_unchanged is True


def test_bounded_fuzz_every_design_meets_the_limits_and_arrives():
    # 12 seeded random requests over the papers' plants, shapers and baselines (the audit's kind): each
    # design meets every requested limit (the pipeline's 1e-9) and ends at its displacement (1e-9
    # relative). A wider run of the same kind (150 requests) found ramps 1e-12 to 2e-8 over the limit by
    # round-off of the kinks' times, and references at max_velocity plus round-off, both now handled.
    rng = np.random.default_rng(2)
    plants = [
        example_plants()[name] for name in ("chatlatanagulchai_eq3", "cusimano_8hz_equal_inertia", "incerti_table_iii")
    ]
    for _ in range(12):
        plant = plants[int(rng.integers(len(plants)))]
        displacement, top, accel = 10 ** rng.uniform(-2, 1), 10 ** rng.uniform(-1, 2), 10 ** rng.uniform(0, 3)
        torque = float(10 ** rng.uniform(-2, 1)) if plant.kind == "two_inertia" and rng.random() < 0.5 else None
        problem = Problem(plant, displacement=displacement, limits=Limits(top, accel, None, torque))
        options = {
            "shaper": str(rng.choice(["zv", "mzv", "zvd", "zvdd", "ei", "2hump_ei"])),
            "baseline": str(rng.choice(["auto", "step", "modified", "multi_step"])),
        }
        result = _design(problem, **options)
        assert not result.limit_violations, (options, result.limit_violations)
        assert result.command.derivative(0)[-1] == pytest.approx(displacement, rel=1e-9), options


@pytest.mark.parametrize("stiffness", [43_000.0, 43_000_000.0])
def test_torque_limited_design_works_in_bounded_memory(stiffness):
    # Issue 23's reproducer (J_M 0.001, J_L 0.01, k 43000: a 330 Hz shaft; 100 rad/s within 0.1 N m, an 11 s
    # ramp) and a 1000 times stiffer shaft (10.4 kHz). The torque check sampled 2000 points per period: 7.3
    # million samples, 1.1 GB, for the first; now the exact peak per breakpoint of the command (models.torque).
    # tracemalloc sees numpy's buffers: the whole pipeline stays under 16 MiB (1.5 MiB measured).
    import tracemalloc

    plant = make_plant(
        kind="two_inertia", motor_inertia_kgm2=0.001, load_inertia_kgm2=0.01, stiffness_nm_per_rad=stiffness
    )
    problem = Problem(plant, target_velocity=100.0, limits=Limits(max_torque_nm=0.1))
    tracemalloc.start()
    try:
        result = _design(problem)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 16 * 2**20
    assert result.metrics.peak_motor_torque_nm <= 0.1 and not result.limit_violations
