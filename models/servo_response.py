"""What the machine does with a command through its drive: the closed loop of models.servo, simulated exactly.

Each output of the closed loop (the motor's position, current, torque, voltage, the load, the tracking error) is
a transfer function of the command's position in partial fractions (``ClosedLoop.modal``); models.simulation's
exact recurrence gives it at the command's breakpoints (no time step, no Python loop over samples). The load's
answer is a full models.simulation.Response, so that its settling and residual vibration are measured as on an
ideal motor (models.metrics), from the closed loop's free state at the command's end.

Saturation: where the linear prediction needs more torque or voltage than the motor's limits, a continuous drive is
simulated again with its limits (models.servo_limits: the current reference and the voltage clamped, the
integrators kept from winding up), and each limit is reported with what the linear loop would need
(``Saturation``: the command's demand through an unlimited drive, its peak and when it first passes the limit).
A sampled drive's prediction stays linear and reports the limits it exceeds, as does a continuous one whose
limited simulation cannot answer within its work cap (``note`` says why).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.modal_data import partial_fraction_taylor
from models.plant_base import Mode
from models.plants import Plant, TransferFunctionPlant
from models.servo import OUTPUTS, ClosedLoop, Drive, ModalOutput, closed_loop
from models.servo_limits import WorkCapExceeded, simulate_limited
from models.servo_sampled import sampled_loop, simulate_sampled
from models.simulation import ModalForm, Response, another_output, simulate

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
_REAL_POLE_TOLERANCE = 1e-12
PREPARED_CACHE = 32  # machines (plant and drive) whose closed loop is kept between simulations
ROUND_OFF = 1e-9  # a numerator term below this share of the largest is the cancellation's round-off


@dataclass(frozen=True)
class Saturation:
    """A limit the linear prediction exceeds: which, its value, the largest |value| and when it is first passed."""

    quantity: str  # "torque_nm" or "voltage_v"
    limit: float
    peak: float
    first_time_s: float


@dataclass(frozen=True)
class DriveResponse:
    """The closed loop's outputs at the command's breakpoints, the load's Response and the limits exceeded."""

    time_s: Array
    motor_position: Array
    motor_velocity: Array
    motor_acceleration: Array
    current_a: Array
    torque_nm: Array
    voltage_v: Array
    tracking_error: Array
    load: Response
    saturation: tuple[Saturation, ...]
    modes: tuple[Mode, ...]  # the closed loop's (ClosedLoop.modes)
    simulation: str = "linear"  # or "limited" (models.servo_limits)
    free_from: int | None = None  # the sample the load's free response is measured from (None: the command's end)
    note: str | None = None  # why a saturated prediction is linear

    @property
    def saturated(self) -> bool:
        return bool(self.saturation)


def modal_form(poles: CArray, output: ModalOutput, taylor_count: int) -> ModalForm:
    """models.simulation's ModalForm of ``output``: its Taylor coefficients at 0, g_m = P_m - sum_j rho_j /
    lambda_j^(m+1) (over every pole), and one entry per real pole or conjugate pair."""
    taylor = partial_fraction_taylor(output.polynomial, output.residues, poles, taylor_count)
    flat = np.abs(poles.imag) <= _REAL_POLE_TOLERANCE * np.abs(poles)
    keep = flat | (poles.imag > 0.0)  # one pole of each conjugate pair, and every real pole
    chosen = np.where(flat, poles.real + 0j, poles)[keep]
    residues = np.where(flat, output.residues.real + 0j, output.residues)[keep]
    weights = np.where(flat[keep], 1.0, 2.0)
    return ModalForm(taylor, chosen, residues, weights)


def transfer_function(loop: ClosedLoop, name: str) -> tuple[Array, Array]:
    """H(s) of an output as polynomials (descending powers): the closed loop as a plant's transfer function."""
    output = loop.modal(name)
    poles = loop.poles
    den = np.real(np.poly(poles))
    num = np.polymul(np.array(output.polynomial[::-1]), den)
    for j, rho in enumerate(output.residues):  # a loop over poles
        others = np.poly(np.delete(poles, j))
        num = np.polyadd(num, rho * others)
    return _without_round_off(np.real(num), float(np.max(np.abs(poles)))), den


def _without_round_off(num: Array, omega: float) -> Array:
    """``num`` without its leading coefficients that are the round-off of terms cancelling (the closed loop's
    relative degree): c_k with |c_k| omega^k below ROUND_OFF of the largest such term, omega the fastest pole
    (the powers of s compared at the frequency where they are largest)."""
    powers = np.arange(num.size - 1, -1, -1, dtype=float)
    with np.errstate(over="ignore"):
        size = np.abs(num) * omega**powers
    negligible = size <= ROUND_OFF * float(np.max(size))
    first = int(np.argmin(negligible)) if not np.all(negligible) else num.size - 1
    return num[first:]


def load_plant(loop: ClosedLoop) -> TransferFunctionPlant:
    """The closed loop from the command to the load, as a transfer-function plant (its modes are the loop's);
    InvalidParameter on ``drive`` where that is not a valid plant (models.plants.TransferFunctionPlant's rules)."""
    num, den = transfer_function(loop, "load_position")
    try:
        return TransferFunctionPlant(tuple(num), tuple(den))
    except InvalidParameter as exc:
        raise InvalidParameter(
            "drive", exc.value, f"the closed loop's transfer function is not usable as a plant: {exc.rule}"
        ) from None


@dataclass(frozen=True)
class _LoadStandIn(TransferFunctionPlant):
    """The closed loop's load transfer function as the simulated load's plant (its G(0), its command input): its
    partial fractions come from the loop's eigenvectors (ClosedLoop.modal), so the polynomial's own checks, which
    refuse poles too clustered for partial fractions of the coefficients, do not apply (a transfer_function plant
    that a family designs for is checked: ``load_plant``)."""

    def __post_init__(self) -> None:
        pass


@dataclass(frozen=True)
class ServoMachine:
    """What a machine's simulations share, built once (``prepared``): the loop, its load's plant, every output's
    partial fractions."""

    loop: ClosedLoop
    load_plant: TransferFunctionPlant
    modal: dict[str, ModalOutput]


@functools.lru_cache(maxsize=PREPARED_CACHE)
def prepared(mechanics: Plant, drive: Drive) -> ServoMachine:
    """The closed loop of ``drive`` on ``mechanics``, its checks passed (stable, exact partial fractions), kept for
    the next command through the same machine (both are frozen: their values are the key)."""
    loop = closed_loop(mechanics, drive)
    num, den = transfer_function(loop, "load_position")
    return ServoMachine(loop, _LoadStandIn(tuple(num), tuple(den)), {name: loop.modal(name) for name in OUTPUTS})


def loop_of(mechanics: Plant, drive: Drive) -> object:
    """The machine's loop, built and checked (InvalidParameter on ``drive`` where it cannot run: unstable,
    repeated poles), continuous or sampled."""
    return sampled_loop(mechanics, drive) if drive.sample_period_s is not None else prepared(mechanics, drive)


def simulate_drive(mechanics: Plant, drive: Drive, command: PiecewiseCommand) -> DriveResponse:
    """``command`` through ``drive`` on ``mechanics`` (module docstring): at the command's breakpoints, or at the
    samples of a sampled drive (models.servo_sampled)."""
    if drive.sample_period_s is not None:
        return _sampled(mechanics, drive, command)
    machine = prepared(mechanics, drive)
    count = command.degree + 1
    poles = machine.loop.poles
    load = simulate(machine.load_plant, command, modal_form(poles, machine.modal["load_position"], count))

    def run(name: str) -> Response:  # the same poles, the load's free responses (models.simulation.another_output)
        return another_output(load, modal_form(poles, machine.modal[name], count))

    motor = run("motor_position")
    values = {name: run(name).load_position for name in ("current_a", "torque_nm", "voltage_v")}
    error = run("tracking_error").load_position
    linear = DriveResponse(
        command.time_s,
        motor.load_position,
        motor.load_velocity,
        motor.load_acceleration,
        values["current_a"],
        values["torque_nm"],
        values["voltage_v"],
        error,
        load,
        _saturation(drive, values, command.time_s),
        machine.loop.modes(),
    )
    if not linear.saturated:
        return linear
    if drive.current is None and all(limit.quantity == "voltage_v" for limit in linear.saturation):
        note = "without a current loop the voltage is what the winding needs, not clamped"
        return dataclasses.replace(linear, note=f"{note}: the prediction is linear past the voltage limit")
    try:
        limited = simulate_limited(mechanics, drive, command, machine.loop, load.modal, machine.load_plant)
    except WorkCapExceeded as exc:
        return dataclasses.replace(linear, note=f"{exc.reason}: the prediction is linear past the limits")
    # the saturation is what the command needs through the loop (the clamped loop's own demand winds up)
    at_limits = _response(limited.command.time_s, limited.values, limited.load, linear.saturation, linear.modes)
    return dataclasses.replace(at_limits, simulation="limited", free_from=limited.free_from)


def _sampled(mechanics: Plant, drive: Drive, command: PiecewiseCommand) -> DriveResponse:
    run = simulate_sampled(mechanics, drive, command, lambda gain: _LoadStandIn((gain,), (1.0,)))
    saturation = _saturation(drive, run.values, run.time_s)
    answer = _response(run.time_s, run.values, run.load, saturation, sampled_loop(mechanics, drive).modes())
    if not saturation:
        return answer
    return dataclasses.replace(answer, note="a sampled drive's limits are reported, not simulated: linear past them")


def _response(
    time_s: Array, values: dict[str, Array], load: Response, saturation: tuple[Saturation, ...], modes: tuple[Mode, ...]
) -> DriveResponse:
    """A DriveResponse of every output by name (models.servo.OUTPUTS)."""
    v = values
    return DriveResponse(
        time_s,
        motor_position=v["motor_position"],
        motor_velocity=v["motor_velocity"],
        motor_acceleration=v["motor_acceleration"],
        current_a=v["current_a"],
        torque_nm=v["torque_nm"],
        voltage_v=v["voltage_v"],
        tracking_error=v["tracking_error"],
        load=load,
        saturation=saturation,
        modes=modes,
    )


def _saturation(drive: Drive, values: dict[str, Array], time_s: Array) -> tuple[Saturation, ...]:
    limits = {"torque_nm": drive.motor.max_torque_nm, "voltage_v": drive.motor.max_voltage_v}
    found = (_exceeded(name, values[name], limit, time_s) for name, limit in limits.items() if np.isfinite(limit))
    return tuple(s for s in found if s is not None)


def _exceeded(name: str, values: Array, limit: float, time_s: Array) -> Saturation | None:
    over = np.abs(values) > limit
    if not np.any(over):
        return None
    return Saturation(name, limit, float(np.max(np.abs(values))), float(time_s[int(np.argmax(over))]))
