"""Plant kinds: the papers' numbers, closed forms, and the numeric/symbolic forms agreeing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from models.errors import InvalidParameter
from models.plants import (
    BeltPlatformPlant,
    ModePlant,
    RigidFlexiblePlant,
    TransferFunctionPlant,
    TwoInertiaPlant,
    example_plants,
    make_plant,
)

PLANTS = example_plants()
TF_TWO_MODES = TransferFunctionPlant((20611800.0,), (1.0, 9.92743, 21881.9, 34801.4, 20611800.0))


def test_incerti_table_iii_mode_matches_paper_and_closed_form():
    plant = PLANTS["incerti_table_iii"]
    (mode,) = plant.modes()
    # Paper/PAPER-NOTES print 31.1769 rad/s and 0.025981 (6 significant digits -> rel 2e-5).
    assert mode.natural_frequency_rad_s == pytest.approx(31.1769, rel=2e-6)
    assert mode.damping_ratio == pytest.approx(0.025981, rel=2e-5)
    # Closed form, eqs. (2)-(4): k_t = 2 k R^2 = 5832, c_t = 9.72, omega_n = sqrt(972), lambda = 1/30.
    assert mode.natural_frequency_rad_s == pytest.approx(math.sqrt(972.0), rel=1e-14)
    assert mode.damping_ratio == pytest.approx(9.72 / (2 * 6.0 * math.sqrt(972.0)), rel=1e-14)
    assert plant.transmission_ratio == pytest.approx(1 / 30, rel=1e-15)
    assert plant.dc_gain == pytest.approx(1 / 30, rel=1e-15)
    assert mode.natural_frequency_hz == pytest.approx(4.962, abs=5e-4)  # PAPER-NOTES: 4.962 Hz


def test_chatlatanagulchai_eq3_mode_is_a_factor_of_the_printed_denominator():
    plant = PLANTS["chatlatanagulchai_eq3"]
    (mode,) = plant.modes()
    # The issue and PAPER-NOTES: 0.57703 rad/s and 0.057724 from eq. (3) as printed.
    assert mode.natural_frequency_rad_s == pytest.approx(0.57703, abs=5e-6)
    assert mode.damping_ratio == pytest.approx(0.057724, abs=5e-7)
    # Independent check: s^2 + 2 zeta w s + w^2 divides 6 s^3 + 90.5 s^2 + 8 s + 30 exactly.
    w, z = mode.natural_frequency_rad_s, mode.damping_ratio
    _, remainder = np.polydiv([6.0, 90.5, 8.0, 30.0], [1.0, 2 * z * w, w * w])
    assert np.max(np.abs(remainder)) < 1e-12
    assert plant.command_input == "velocity"
    assert plant.dc_gain == 0.0  # x1 = P(s) s Theta_m(s): no position gain


def test_two_inertia_follows_cusimano_eqs_1_to_3():
    plant = TwoInertiaPlant(0.005, 0.02, 40.0, 0.03)
    (mode,) = plant.modes()
    assert mode.natural_frequency_rad_s == pytest.approx(math.sqrt(40.0 / 0.02), rel=1e-15)
    assert mode.damping_ratio == pytest.approx(0.03 / (2 * math.sqrt(40.0 * 0.02)), rel=1e-15)
    poles = np.roots(plant.load_transfer_function()[1])
    assert np.max(np.abs(np.sort_complex(poles) - np.sort_complex([mode.pole, mode.pole.conjugate()]))) < 1e-10


@pytest.mark.parametrize("name", [*sorted(PLANTS), "tf"])
def test_mode_matches_the_poles_of_the_transfer_function(name):
    plant = PLANTS.get(name, TF_TWO_MODES)
    poles = np.roots(plant.load_transfer_function()[1])
    upper = sorted((p for p in poles if p.imag > 0), key=abs)
    assert len(upper) == len(plant.modes())
    for pole, mode in zip(upper, plant.modes(), strict=True):
        assert abs(pole - mode.pole) <= 1e-9 * abs(pole)
        assert mode.damped_frequency_rad_s == pytest.approx(pole.imag, rel=1e-9)
        assert mode.damped_period_s == pytest.approx(2 * math.pi / pole.imag, rel=1e-9)
        assert mode.decay_rate_1_s == pytest.approx(-pole.real, rel=1e-6, abs=1e-12)


def test_transfer_function_modes_are_its_complex_pairs():
    low, high = TF_TWO_MODES.modes()
    # The example's denominator is (s^2 + 2 0.02 w1 s + w1^2)(s^2 + 2 0.03 w2 s + w2^2), 6 digits.
    assert low.natural_frequency_hz == pytest.approx(5.0, rel=1e-5)
    assert low.damping_ratio == pytest.approx(0.02, rel=1e-4)
    assert high.natural_frequency_hz == pytest.approx(23.0, rel=1e-5)
    assert high.damping_ratio == pytest.approx(0.03, rel=1e-4)


@pytest.mark.parametrize("name", [*sorted(PLANTS), "tf"])
def test_state_space_realises_the_load_transfer_function(name):
    plant = PLANTS.get(name, TF_TWO_MODES)
    ss = plant.state_space()
    num, den = signal.ss2tf(ss.a, ss.b, ss.c, ss.d)
    lnum, lden = plant.load_transfer_function()
    # Compare as frequency responses (coefficients may differ by a common factor).
    s = 1j * np.logspace(-2, 3, 40)
    ours = np.polyval(lnum, s) / np.polyval(lden, s)
    theirs = np.polyval(num[0], s) / np.polyval(den, s)
    assert np.max(np.abs(ours - theirs) / np.maximum(np.abs(ours), 1e-300)) < 1e-9


@pytest.mark.parametrize("name", [*sorted(PLANTS), "tf"])
def test_symbolic_form_evaluates_to_the_numeric_form(name):
    plant = PLANTS.get(name, TF_TWO_MODES)
    symbolic = plant.symbolic()
    a, b, c, d = (np.array(m) for m in symbolic.function()(plant.symbolic_parameter_values()))
    ss = plant.state_space()
    for sym, num in ((a, ss.a), (b, ss.b), (c, ss.c), (d, ss.d)):
        np.testing.assert_allclose(sym, num, rtol=1e-14, atol=0)
    assert len(symbolic.parameter_names) == symbolic.parameters.numel()


def test_symbolic_form_depends_only_on_the_kind_and_shape():
    a, b = TwoInertiaPlant(1.0, 2.0, 3.0), TwoInertiaPlant(5.0, 6.0, 7.0, 0.1)
    assert a.symbolic_key() == b.symbolic_key()
    assert TF_TWO_MODES.symbolic_key() != TransferFunctionPlant((1.0,), (1.0, 1.0, 4.0)).symbolic_key()


@pytest.mark.parametrize(
    ("kind", "params", "field"),
    [
        ("mode", {"natural_frequency_hz": -1.0}, "natural_frequency_hz"),
        ("mode", {"natural_frequency_hz": float("nan")}, "natural_frequency_hz"),
        ("mode", {"natural_frequency_hz": 1e7}, "natural_frequency_hz"),
        ("mode", {"natural_frequency_hz": 5.0, "damping_ratio": 1.0}, "damping_ratio"),
        ("mode", {"natural_frequency_hz": 5.0, "damping_ratio": -0.1}, "damping_ratio"),
        (
            "two_inertia",
            {"motor_inertia_kgm2": -1.0, "load_inertia_kgm2": 1.0, "stiffness_nm_per_rad": 1.0},
            "motor_inertia_kgm2",
        ),
        (
            "two_inertia",
            {"motor_inertia_kgm2": 1.0, "load_inertia_kgm2": 0.0, "stiffness_nm_per_rad": 1.0},
            "load_inertia_kgm2",
        ),
        (
            "two_inertia",
            {"motor_inertia_kgm2": 1.0, "load_inertia_kgm2": 1.0, "stiffness_nm_per_rad": float("inf")},
            "stiffness_nm_per_rad",
        ),
        # zeta = c / (2 sqrt(k J_L)) = 3 / 2 >= 1: overdamped, no mode
        (
            "two_inertia",
            {
                "motor_inertia_kgm2": 1.0,
                "load_inertia_kgm2": 1.0,
                "stiffness_nm_per_rad": 1.0,
                "damping_nms_per_rad": 3.0,
            },
            "stiffness_nm_per_rad",
        ),
        (
            "belt_platform",
            {
                "platform_inertia_kgm2": 6.0,
                "branch_stiffness_n_per_m": 9e4,
                "branch_damping_ns_per_m": -150.0,
                "motor_pulley_radius_m": 0.06,
                "platform_pulley_radius_m": 0.18,
                "gear_ratio": 0.1,
            },
            "branch_damping_ns_per_m",
        ),
        (
            "rigid_flexible",
            {
                "drive_mass_kg": 2.0,
                "load_mass_kg": 3.0,
                "stiffness_n_per_m": 1.0,
                "damping_ns_per_m": 0.1,
                "drive_damping_ns_per_m": 0.0,
            },
            "drive_damping_ns_per_m",
        ),
        ("transfer_function", {"numerator": (1.0,), "denominator": (1.0, 0.0)}, "denominator"),  # pole at 0
        ("transfer_function", {"numerator": (1.0,), "denominator": (1.0, -1.0, 4.0)}, "denominator"),  # RHP
        ("transfer_function", {"numerator": (1.0,), "denominator": (1.0, 2.0, 1.0)}, "denominator"),  # repeated
        ("transfer_function", {"numerator": (1.0, 2.0, 3.0), "denominator": (1.0, 2.0)}, "numerator"),  # improper
        (
            "transfer_function",
            {"numerator": (1.0, 2.0), "denominator": (1.0, 2.0), "command_input": "velocity"},
            "numerator",
        ),
        ("transfer_function", {"numerator": (0.0,), "denominator": (1.0, 2.0)}, "numerator"),
        ("transfer_function", {"numerator": (1.0,), "denominator": (0.0, 2.0)}, "denominator"),
        ("pendulum", {}, "kind"),
    ],
)
def test_invalid_parameters_name_the_field(kind, params, field):
    with pytest.raises(InvalidParameter) as info:
        make_plant(kind, **params)
    assert info.value.field == field
    assert info.value.rule


def test_undamped_transfer_function_mode_is_allowed():
    plant = TransferFunctionPlant((4.0,), (1.0, 0.0, 4.0))
    (mode,) = plant.modes()
    assert mode.natural_frequency_rad_s == pytest.approx(2.0, rel=1e-14)
    assert mode.damping_ratio == 0.0


def test_mode_plant_transfer_function_is_the_papers_model():
    plant = ModePlant(5.0, 0.1)
    w = 2 * math.pi * 5.0
    num, den = plant.load_transfer_function()
    np.testing.assert_allclose(num, [2 * 0.1 * w, w * w], rtol=1e-15)
    np.testing.assert_allclose(den, [1.0, 2 * 0.1 * w, w * w], rtol=1e-15)


def test_rigid_flexible_denominator_is_eq3_as_printed():
    num, den = RigidFlexiblePlant(2.0, 3.0, 1.0, 0.1, 30.0).command_transfer_function()
    # m0 m1 = 6; m0 c + m1 c + m1 c0 = 0.2 + 0.3 + 90 = 90.5; m0 k + m1 k + c c0 = 2 + 3 + 3 = 8; c0 k = 30
    np.testing.assert_allclose(den, [6.0, 90.5, 8.0, 30.0], rtol=1e-15)
    np.testing.assert_allclose(num, [0.1, 1.0], rtol=1e-15)


def test_belt_platform_energy_coefficients():
    plant = PLANTS["incerti_table_iii"]
    assert isinstance(plant, BeltPlatformPlant)
    assert plant.energy_inertia == 6.0
    assert plant.energy_stiffness == pytest.approx(5832.0, rel=1e-15)  # 2 k R^2
