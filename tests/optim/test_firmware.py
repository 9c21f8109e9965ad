"""optim.families.input_shaped.firmware: the Klipper, RepRapFirmware and Marlin settings of a designed shaper.

Independent references: the impulses printed by Klipper's own code (klippy/extras/shaper_defs.py at
Klipper3d/klipper 84104bbbd, run as init_shaper(name, f, zeta) and normalised as kin_shaper.c does);
the catalogue's shapers (optim.families.input_shaped.shapers) where a firmware type should coincide with them; Klipper's
transcription in tests/shaper_oracle.py; V measured by exact simulation (tests.shaper_oracle
.v_by_simulation), never by the V formula the module uses; and the firmware strings parsed back by
the rules their documentation states:

- Klipper: docs/Config_Reference.md, [input_shaper] (https://www.klipper3d.org/Config_Reference.html#input_shaper):
  shaper_type_x, shaper_freq_x (Hz, >= 0), damping_ratio_x (0 .. the type's maximum); Klipper reads
  printer.cfg with Python's configparser.
- RepRapFirmware: the G-code dictionary's M593
  (https://docs.duet3d.com/User_manual/Reference/Gcodes#m593-configure-input-shaping): P"type" one of none,
  zvd, zvdd, zvddd, mzv, ei2, ei3, custom; F in Hz; S the damping; RRF 3.6: H the individual amplitudes of
  each impulse except the last (the last is 1 minus their sum), T the cumulative delays of each impulse
  except the first, strictly increasing; RRF 3.3-3.5: H cumulative amplitudes, T durations of each impulse
  except the last. At most 5 impulses (AxisShaper.h MaxImpulses = 5); F within 4..1000 Hz, S within 0..0.99
  (AxisShaper.cpp, TryGetLimitedFValue).
- Marlin: https://marlinfw.org/docs/gcode/M493.html (MarlinDocumentation _gcode/M493.md of 2026-06-10):
  S0/1, C0..8 (NONE, ZV, ZVD, ZVDD, ZVDDD, EI, 2HEI, 3HEI, MZV), A (Hz), I zeta in [0.01, 1], Q vtol in
  [0, 1], axis flags X/Y/Z/E.
"""

from __future__ import annotations

import configparser
import math
import re
from typing import Any

import numpy as np
import pytest

from app.presenters import present
from models.plants import Mode
from models.shapers import ImpulseSequence
from optim.families.input_shaped.firmware import (
    KLIPPER_MAX_DAMPING,
    RRF_FREQUENCY_HZ,
    closest,
    curve_distance,
    fixed,
    klipper_impulses,
    marlin_impulses,
    rrf_impulses,
)
from optim.families.input_shaped.firmware_blocks import firmware_block as firmware_report
from optim.families.input_shaped.shapers import ShaperDesign, design_for_modes, design_shaper
from tests.shaper_oracle import klipper_ei, klipper_hump_ei, klipper_mzv, v_by_simulation


def firmware_block(design: ShaperDesign) -> dict[str, Any]:
    """``design.firmware`` as the answer shows it (app.presenters)."""
    return present(firmware_report(design))  # type: ignore[no-any-return]


def mode(frequency_hz: float, zeta: float = 0.0) -> Mode:
    return Mode(2 * math.pi * frequency_hz, zeta)


def v_percent(impulses: ImpulseSequence, m: Mode) -> float:
    """100 V by exact simulation of the mode (independent of models.shapers.percentage_vibration)."""
    return 100.0 * v_by_simulation(impulses.amplitudes, impulses.times_s, m.natural_frequency_rad_s, m.damping_ratio)


# Printed by Klipper's shaper_defs.init_shaper at 84104bbbd (12 significant digits), amplitudes / sum(A).
KLIPPER_PRINTED = {
    ("zvd", 40.0, 0.1): (
        [0.334414907891, 0.487742547524, 0.177842544584],
        [0.0, 0.0125629726907, 0.0251259453815],
    ),
    ("mzv", 23.7, 0.19): (
        [0.435142673907, 0.390045911302, 0.174811414791],
        [0.0, 0.0161163589492, 0.0322327178983],
    ),
    ("ei", 23.7, 0.19): ([0.4495246528, 0.4110749929, 0.1394003543], [0.0, 0.0220311843602, 0.0429769571978]),
    ("2hump_ei", 23.7, 0.19): (
        [0.379442869174, 0.343332164693, 0.201948582401, 0.0752763837317],
        [0.0, 0.0233117385738, 0.0435154679662, 0.0626178705021],
    ),
    ("3hump_ei", 23.7, 0.19): (
        [0.367275340111, 0.293389632306, 0.187349151243, 0.101100102903, 0.0508857734368],
        [0.0, 0.0272850568354, 0.0476901637553, 0.0659241391561, 0.0846094962658],
    ),
}


@pytest.mark.parametrize("key", list(KLIPPER_PRINTED))
def test_klipper_impulses_are_klippers_own(key):
    kind, frequency, zeta = key
    amplitudes, times = KLIPPER_PRINTED[key]
    got = klipper_impulses(kind, frequency, zeta)
    # 12 significant digits printed: 5e-12 relative, so 1e-11 absolute on numbers below 1
    np.testing.assert_allclose(got.amplitudes, amplitudes, rtol=0, atol=1e-11)
    np.testing.assert_allclose(got.times_s, times, rtol=0, atol=1e-13)


@pytest.mark.parametrize("frequency", [40.0, 23.7])
@pytest.mark.parametrize("zeta", [0.0, 0.1, 0.19])
def test_klipper_zv_mzv_zvd_are_the_catalogues(frequency, zeta):
    # Both are closed forms of the same definitions (ZV, ZVD: Singer & Seering; MZV: Klipper's): equal to
    # round-off; the oracle transcription of Klipper's MZV agrees too.
    for kind in ("zv", "mzv", "zvd"):
        ours = design_shaper(kind, mode(frequency, zeta)).impulses
        theirs = klipper_impulses(kind, frequency, zeta)
        np.testing.assert_allclose(theirs.amplitudes, ours.amplitudes, rtol=0, atol=1e-14)
        np.testing.assert_allclose(theirs.times_s, ours.times_s, rtol=1e-13, atol=0)
    a, t = klipper_mzv(frequency, zeta)
    np.testing.assert_allclose(klipper_impulses("mzv", frequency, zeta).amplitudes, np.array(a) / sum(a), atol=1e-14)
    np.testing.assert_allclose(klipper_impulses("mzv", frequency, zeta).times_s, t, rtol=1e-13)


@pytest.mark.parametrize("zeta", [0.0, 0.1])
def test_klipper_ei_types_are_fits_of_the_catalogues(zeta):
    # Klipper's EI types are polynomial fits (Singhose): close to the exact catalogue shapers, not equal.
    # Seen: amplitudes within 1.3e-3 of the exact ones (0.2621605 vs 1.05/4 for the undamped EI), times
    # within 0.7 % of the duration (3hump_ei at zeta 0.1); bounds 2e-3 and 1 %. Their V at the design
    # frequency is within 0.5 points of the 5 % tolerance (measured by simulation).
    m = mode(40.0, zeta)
    for kind, humps in (("ei", 1), ("2hump_ei", 2), ("3hump_ei", 3)):
        ours = design_shaper(kind, m).impulses
        theirs = klipper_impulses(kind, 40.0, zeta)
        assert theirs.count == ours.count
        np.testing.assert_allclose(theirs.amplitudes, ours.amplitudes, atol=2e-3)
        np.testing.assert_allclose(theirs.times_s, ours.times_s, atol=1e-2 * ours.duration_s)
        if humps == 1:
            a, t = klipper_ei(40.0, zeta, 0.05)
        else:
            a, t = klipper_hump_ei(humps, 40.0, zeta)
        np.testing.assert_allclose(theirs.amplitudes, np.array(a) / sum(a), atol=1e-14)
        np.testing.assert_allclose(theirs.times_s, t, rtol=1e-12, atol=1e-15)
        if humps % 2 == 1:  # odd hump counts have their middle hump, V = 5 %, at the design frequency
            assert v_percent(theirs, m) == pytest.approx(5.0, abs=0.5)


def _klipper_section(text: str) -> configparser.SectionProxy:
    parser = configparser.RawConfigParser()
    parser.read_string(text)
    return parser["input_shaper"]


def _m593(command: str) -> dict[str, str]:
    """M593's parameters as the dictionary lists them (a letter, then a quoted string or a number list)."""
    match = re.fullmatch(r'M593( P"[a-z0-9]+")?( F[0-9.]+)?( S[0-9.]+)?( H[0-9.:]+)?( T[0-9.:]+)?', command)
    assert match, command
    return {part[0]: part[1:] for part in command.split()[1:]}


def _m493(command: str) -> dict[str, str]:
    match = re.fullmatch(r"M493 S1 X C[0-8] A[0-9.]+ I[0-9.]+( Q[0-9.]+)?", command)
    assert match, command
    return {part[0]: part[1:] for part in command.split()[1:]}


def _m493_v1(command: str) -> dict[str, str]:
    """Before FTM V2 (M493.cpp at 485fbf20): X<mode 0-8> selects X's shaper; A (Hz) within [FTM_MIN_SHAPE_FREQ,
    FTM_FS / 2], I within [0.01, 1], Q within [0, 1] and only for an EI type (modes 5-7)."""
    match = re.fullmatch(r"M493 S1 X([0-8]) A([0-9.]+) I([0-9.]+)( Q([0-9.]+))?", command)
    assert match, command
    mode, frequency, zeta = int(match[1]), float(match[2]), float(match[3])
    assert 10.0 <= frequency <= 500.0 and 0.01 <= zeta <= 1.0
    assert match[4] is None or (5 <= mode <= 7 and 0.0 <= float(match[5]) <= 1.0)
    return {"C": match[1], "A": match[2], "I": match[3], **({"Q": match[5]} if match[4] else {})}


def test_a_40_hz_zvd_design_gives_the_documented_strings():
    # The acceptance: shaper_type_x: zvd and shaper_freq_x: 40, written exactly so.
    design = design_shaper("zvd", mode(40.0, 0.0))
    block = firmware_block(design)
    klipper = block["klipper"]
    assert "shaper_type_x: zvd\n" in klipper["section"]
    assert "shaper_freq_x: 40\n" in klipper["section"]
    section = _klipper_section(klipper["section"])
    assert section["shaper_type_x"] == "zvd"
    assert float(section["shaper_freq_x"]) == 40.0
    assert 0.0 <= float(section["damping_ratio_x"]) <= KLIPPER_MAX_DAMPING["zvd"]
    assert klipper["exact"] and klipper["note"] is None
    assert klipper["residual_percent"] < 1e-9
    # RRF: the dictionary's own example form M593 P"zvd" F40.5, here with S (0..0.99)
    rrf = block["reprapfirmware"]
    assert rrf["command"] == 'M593 P"zvd" F40 S0'
    params = _m593(rrf["command"])
    assert (
        params["P"] == '"zvd"'
        and RRF_FREQUENCY_HZ[0] <= float(params["F"]) <= 1000.0
        and 0.0 <= float(params["S"]) <= 0.99
    )
    # Marlin: the page's example form M493 S1 XY C2 A37, on X, with the damping at I's lower bound 0.01
    marlin = block["marlin"]
    assert marlin["command"] == "M493 S1 X C2 A40 I0.01"
    v2 = {key: value for key, value in _m493(marlin["command"]).items() if key in "CAIQ"}
    assert _m493_v1(marlin["command_v1"]) == v2  # the same settings before FTM V2
    params = _m493(marlin["command"])
    assert params["C"] == "2" and 0.01 <= float(params["I"]) <= 1.0
    assert block["marlin_reason"] is None and block["reprapfirmware_reason"] is None


def _rrf_36(command: str) -> ImpulseSequence:
    """The impulses RRF 3.6 applies for M593 P"custom" H.. T.. (individual H; cumulative T), as AxisShaper::Configure
    reads them (3.6.0-beta.1): T's values are padded to 4 when one is given (GetFloatArray), and their count must
    equal H's ("Number of delays must be same as number of amplitudes"); without T the delays are i x half the
    damped period of F and S."""
    params = _m593(command)
    h = [float(x) for x in params["H"].split(":")]
    if "T" in params:
        t = [float(x) for x in params["T"].split(":")]
        t = t * 4 if len(t) == 1 else t  # a single value is padded to the array's length
        assert len(h) == len(t) <= 4, "Number of delays must be same as number of amplitudes"
    else:
        frequency, zeta = float(params["F"]), float(params.get("S", "0.05"))  # 3.6's default S is 0.05
        assert RRF_FREQUENCY_HZ[0] <= frequency <= RRF_FREQUENCY_HZ[1] and 0.0 <= zeta <= 0.99
        t = [0.5 * i / (frequency * math.sqrt(1.0 - zeta * zeta)) for i in range(1, len(h) + 1)]
    assert sum(h) < 1.0 and all(np.diff([0.0, *t]) > 0)
    return ImpulseSequence(np.array([*h, 1.0 - sum(h)]), np.array([0.0, *t]))


def _rrf_35(command: str) -> ImpulseSequence:
    """The impulses RRF 3.4/3.5 applies (cumulative H rising to below 1; T durations between impulses)."""
    params = _m593(command)
    h = [float(x) for x in params["H"].split(":")]
    t = [float(x) for x in params["T"].split(":")]
    assert len(h) == len(t) <= 4 and all(np.diff(h) > 0) and h[-1] < 1.0
    return ImpulseSequence(np.diff([0.0, *h, 1.0]), np.concatenate(([0.0], np.cumsum(t))))


@pytest.mark.parametrize(
    "design",
    [
        design_shaper("ei", mode(40.0, 0.05)),
        design_shaper("3hump_ei", mode(55.0, 0.0)),
        design_shaper("mzv", mode(40.0, 0.1)),
        design_shaper("zv", mode(40.0, 0.0)),
        design_for_modes("zv", (mode(40.0, 0.0), mode(95.0, 0.02))),
    ],
    ids=["ei", "3hump_ei", "damped_mzv", "zv", "zv_two_modes"],
)
def test_rrf_custom_carries_the_designs_impulses_in_both_conventions(design):
    rrf = firmware_block(design)["reprapfirmware"]
    assert rrf["shaper_type"] == "custom" and rrf["exact"]
    for parse in (_rrf_36(rrf["command"]), _rrf_35(rrf["command_3_5"])):
        # 10 significant digits written: 5e-10 relative
        np.testing.assert_allclose(parse.amplitudes, design.impulses.amplitudes, atol=2e-9)
        np.testing.assert_allclose(parse.times_s, design.impulses.times_s, rtol=2e-9, atol=0)
    # the custom shaper carries every mode: what it leaves there is what the design leaves (V of the
    # design's impulses by simulation at each designed mode)
    for m, left in zip(design.modes[1:], rrf["other_modes_shaper_residual_percent"], strict=True):
        assert left == pytest.approx(v_percent(design.impulses, m), abs=1e-6)


def test_rrf_names_where_its_definitions_are_ours():
    # RRF's zvd, zvdd, zvddd are the binomial ZV-D shapers (AxisShaper.cpp), so they are named; its mzv is
    # Klipper's reversed in time, equal to ours only without damping.
    for kind, zeta in (("zvd", 0.1), ("zvdd", 0.05), ("zvddd", 0.0), ("mzv", 0.0)):
        design = design_shaper(kind, mode(40.0, zeta))
        rrf = firmware_block(design)["reprapfirmware"]
        assert rrf["shaper_type"] == kind and rrf["exact"], rrf
        np.testing.assert_allclose(rrf_impulses(kind, 40.0, zeta).amplitudes, design.impulses.amplitudes, atol=1e-14)
    damped = rrf_impulses("mzv", 40.0, 0.1)
    np.testing.assert_allclose(damped.amplitudes, klipper_impulses("mzv", 40.0, 0.1).amplitudes[::-1], atol=1e-15)


def test_rrf_beyond_five_impulses_names_the_nearest_type_and_its_residual():
    m = mode(40.0, 0.02)
    design = design_shaper("zvdddd", m)
    rrf = firmware_block(design)["reprapfirmware"]
    assert rrf["shaper_type"] == "zvddd" and not rrf["exact"] and "6 impulses" in rrf["note"]
    # ZVDDD also cancels the design mode: V by simulation ~ 0
    assert rrf["shaper_residual_percent"] == pytest.approx(v_percent(rrf_impulses("zvddd", 40.0, 0.02), m), abs=1e-8)


def test_klipper_closest_type_minimises_the_curve_distance():
    m = mode(40.0, 0.05)
    design = design_shaper("zvdd", m)
    klipper = firmware_block(design)["klipper"]
    options = {k: klipper_impulses(k, 40.0, 0.05) for k in KLIPPER_MAX_DAMPING}
    distances = {k: curve_distance(v, design.impulses, m) for k, v in options.items()}
    assert klipper["shaper_type"] == min(distances, key=distances.__getitem__) == closest(options, design.impulses, m)
    assert "no zvdd" in klipper["note"] and not klipper["exact"]
    # without a move-specific residual the block reports V of Klipper's impulses (simulated) at the mode
    assert klipper["residual_percent"] == pytest.approx(v_percent(options[klipper["shaper_type"]], m), abs=1e-8)


def test_klipper_caps_the_damping_at_the_types_maximum():
    design = design_shaper("3hump_ei", mode(60.0, 0.25), 0.05)
    klipper = firmware_block(design)["klipper"]
    assert klipper["damping_ratio"] == KLIPPER_MAX_DAMPING["3hump_ei"] == 0.2
    assert "damping_ratio_x: 0.2\n" in klipper["section"] and "up to 0.2" in klipper["note"]


def test_marlin_quantises_the_delays_to_its_1_khz_trajectory():
    # 40 Hz, zeta 0.05: T_d / 2 = 12.5156 ms, so Marlin's delays are 13 and 26 ms (LROUND at FTM_FS =
    # 1000 Hz); the ZVD amplitudes with damping are exact. V by simulation of those impulses.
    m = mode(40.0, 0.05)
    design = design_shaper("zvd", m)
    marlin = firmware_block(design)["marlin"]
    assert marlin["command"] == "M493 S1 X C2 A40 I0.05"
    applied = ImpulseSequence(design.impulses.amplitudes, np.array([0.0, 0.013, 0.026]))
    assert not marlin["exact"]
    assert marlin["shaper_residual_percent"] == pytest.approx(v_percent(applied, m), rel=1e-8)
    assert marlin["shaper_residual_percent"] > 0.1  # the 4 % frequency error of the grid leaves ~0.4 %
    np.testing.assert_allclose(marlin_impulses("zvd", 40.0, 0.05, 0.05).times_s, [0.0, 0.013, 0.026], atol=1e-15)


def test_marlin_ei_takes_the_designs_tolerance():
    design = design_shaper("ei", mode(50.0, 0.0), 0.1)
    marlin = firmware_block(design)["marlin"]
    params = _m493(marlin["command"])
    assert params["C"] == "5" and params["Q"] == "0.1" and 0.0 <= float(params["Q"]) <= 1.0
    assert _m493_v1(marlin["command_v1"]) == {"C": "5", "A": "50", "I": params["I"], "Q": "0.1"}


@pytest.mark.parametrize(
    ("design", "reason"),
    [
        (design_for_modes("zvd", (mode(40.0), mode(90.0))), "one shaper per axis"),
        (design_shaper("zvdddd", mode(40.0)), "not zvdddd"),
        (design_shaper("zvd", mode(10.0)), "FTM_MIN_SHAPE_FREQ"),
        (design_shaper("zvd", mode(600.0)), "FTM_FS / 2"),
    ],
    ids=["two_modes", "zvdddd", "10_hz", "600_hz"],
)
def test_marlin_is_null_with_its_reason_where_it_cannot(design, reason):
    block = firmware_block(design)
    assert block["marlin"] is None and reason in block["marlin_reason"]


def test_rrf_is_null_outside_its_frequency_range():
    block = firmware_block(design_shaper("zvd", mode(2.0)))
    assert block["reprapfirmware"] is None and "5.722 Hz (Duet 3" in block["reprapfirmware_reason"]
    assert block["klipper"]["section"].count("\n") == 4  # Klipper takes any frequency >= 0


def test_numbers_are_fixed_point():
    assert [fixed(v) for v in (40.0, 0.0, -0.0, 1e-5, 0.1, 123456.7891234, 2.5e-12)] == [
        "40",
        "0",
        "0",
        "0.00001",
        "0.1",
        "123456.7891",
        "0.0000000000025",
    ]


@pytest.mark.parametrize("name", ["zv", "mzv", "zvd", "zvdd", "zvdddddddd", "ei", "2hump_ei", "3hump_ei"])
def test_every_shaper_at_any_damping_and_frequency_gives_finite_settings(name):
    # Bounded sweep over the plant ranges (0.01 Hz .. 5 kHz; damping up to 0.9999, which the damping bounds
    # of the firmwares must absorb without dividing by sqrt(1 - zeta^2) = 0; every design also evaluates
    # all of Klipper's and RRF's types there, whose hump fits break down at high damping). The EI shapers
    # exist up to zeta ~0.3-0.45 only (their root-finding to that end is slow, so two dampings).
    from models.errors import Infeasible

    dampings = (0.0, 0.2) if "ei" in name else (0.0, 0.3, 0.95, 0.9999)
    for frequency in (0.05, 3.0, 40.0, 700.0, 5000.0):
        for zeta in dampings:
            try:
                design = design_shaper(name, mode(frequency, zeta))
            except Infeasible:  # EI shapers end where their conditions have no solution
                continue
            block = firmware_block(design)
            for key in ("klipper", "reprapfirmware", "marlin"):
                item = block[key]
                assert (item is None) == (block.get(f"{key}_reason") is not None) or key == "klipper"
                if item is not None:
                    assert math.isfinite(item["residual_percent"]) and math.isfinite(item["shaper_residual_percent"])
                    text = item.get("section") or item["command"]
                    assert "e-" not in text and "nan" not in text and "inf" not in text, text


def test_rrf_f_range_is_the_step_clock_over_131070_and_a_zv_is_placed_by_f():
    """RepRapFirmware's M593 F minimum is StepClockRate / (2 x 65535) (AxisShaper.cpp): 750 kHz on Duet 3, 5.72 Hz;
    937.5 kHz on Duet 2, 7.15 Hz (the issue's F4.5 was refused on both). A ZV (two impulses) is P"custom" with H
    and F only: 3.6 refuses a single T (padded to four delays)."""
    assert RRF_FREQUENCY_HZ[0] == pytest.approx(5.7221, abs=1e-4)
    low = firmware_report(design_shaper("zvd", mode(4.5, 0.0)))
    assert low.reprapfirmware is None and "5.722 Hz (Duet 3; 7.153 Hz on Duet 2" in (low.reprapfirmware_reason or "")
    duet3 = present(firmware_report(design_shaper("zvd", mode(6.5, 0.0))))["reprapfirmware"]
    assert duet3["command"] == 'M593 P"zvd" F6.5 S0' and "needs a Duet 3 board" in duet3["note"]
    design = design_shaper("zv", mode(40.0, 0.05))
    rrf = present(firmware_report(design))["reprapfirmware"]
    assert "T" not in _m593(rrf["command"]) and "T" in _m593(rrf["command_3_5"])
    np.testing.assert_allclose(_rrf_36(rrf["command"]).times_s, design.impulses.times_s, rtol=1e-9)
    np.testing.assert_allclose(_rrf_35(rrf["command_3_5"]).times_s, design.impulses.times_s, rtol=1e-9)
    with pytest.raises(AssertionError, match="Number of delays"):  # the form 3.6.0-beta.1 refuses
        _rrf_36('M593 P"custom" H0.5 T0.0125')
