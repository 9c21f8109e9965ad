"""POST /v1/identify: vibration modes from a measured record, and a design for them (the use case:
app.services.identify).

A JSON body (``time_s``, ``signal``) is the original form: a free vibration fitted with one damped sinusoid
(Biagiotti eq. 16, the two-peak estimate still reported for comparison) and the tuned smoother. A ``text/csv``
body is a measured record (a time column and one or more signal columns, e.g. an accelerometer's x, y, z;
optionally the known command): its Welch spectrum, peaks and a sum of damped sinusoids fitted per mode with 95 %
intervals (optim.identification.modal), the record's quality, and with a move and limits in the query the
fastest design whose 5 % band covers the lowest mode's interval (app.services.recommend), each candidate run
through the family endpoints' pipeline (app.services.profile.profile).
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, Query, Request
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples.identify import CSV_EXAMPLE, KLIPPER_PSD_EXAMPLE
from app.examples.identify import EXAMPLES as IDENTIFY_EXAMPLES
from app.json_bodies import JSONRoute
from app.responses import NumpyJSONResponse
from app.schemas.identify import IdentifyMeasurementResponse, IdentifySpectrumResponse, MeasurementParams
from app.schemas.smoothers import IdentifyRequest, IdentifyResponse
from app.services.identify import identify_csv, identify_respond, runner
from models.errors import InvalidParameter

router = APIRouter(prefix="/v1", tags=["smoothers"], route_class=JSONRoute)

CSV_MEDIA_TYPE = "text/csv"


OPENAPI_BODY: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": IdentifyRequest.model_json_schema()},
            CSV_MEDIA_TYPE: {
                "schema": {"type": "string"},
                "examples": {
                    "accelerometer_record": {
                        "summary": "A free vibration measured by a three-axis accelerometer",
                        "value": CSV_EXAMPLE,
                    },
                    "klipper_resonances": {
                        "summary": "Klipper's resonance CSV (add ?target=klipper for its input shaper)",
                        "value": KLIPPER_PSD_EXAMPLE,
                    },
                },
                "description": "A header row, a time column (time_s, or the first column; seconds) and one or more "
                "signal columns; a column named command (or command_column) is the known command.",
            },
        },
    }
}


def _is_csv(content_type: str | None) -> bool:
    return (content_type or "").split(";", 1)[0].strip().lower() == CSV_MEDIA_TYPE


def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        rule = f"the CSV is not UTF-8 (byte {exc.start})"
        raise problems.ProblemError(
            "malformed-body", rule, field="body", errors=[{"field": "body", "value": None, "rule": rule}]
        ) from None


# --- the route --------------------------------------------------------------------------------------------


@router.post(
    "/identify",
    summary="Identify vibration modes from a record (JSON free vibration, or a CSV measurement) and recommend a design",
    response_model=IdentifyResponse | IdentifyMeasurementResponse | IdentifySpectrumResponse,
    responses=problems.responses(400, 413, 422, 503),
    openapi_extra=OPENAPI_BODY,
)
async def identify_mode(
    body: Annotated[Any, Body(openapi_examples=IDENTIFY_EXAMPLES)],
    request: Request,
    settings: SettingsDep,
    pool: PoolDep,
    threads: ThreadsDep,
    params: Annotated[MeasurementParams, Query()],
) -> NumpyJSONResponse:
    """**application/json** (``time_s``, ``signal``): fit A e^(sigma t) cos(Omega t + phi) + offset to a free
    vibration by least squares (Sec. V-A asks for the period T0 and the decay sigma, eq. 16, read from two
    peaks; the fit uses every sample and reports its quality), and tune the damped harmonic smoother. Records
    with fewer than 2 periods, fewer than 4 samples per period or no oscillation clearly above the noise are
    refused (422, field ``signal`` or ``time_s``). The query parameters apply to CSV bodies only.

    **text/csv**: a header row, a time column (``time_s``, or the first column; seconds, uniform or nearly:
    jitter is interpolated, a gap refused) and up to 16 signal columns (e.g. ``accel_x,accel_y,accel_z``), at
    most VIBFREE_IDENTIFY_MAX_ROWS rows. The fit starts at ``start_s``, else where a ``command`` column (the known
    command the record responds to) last changes (the residual vibration after the command ends is a free
    vibration), else at the record's largest excursion. Returns the Welch spectrum (rectangular window,
    summed over the signals, at most 2049 points), and per mode (its peaks start the fit) the natural
    frequency and damping ratio of a sum of damped sinusoids fitted to every signal at once (shared
    frequencies and decays; scipy.optimize.least_squares by variable projection) with 95 % intervals from
    the fit's covariance (Student t), the record's quality and warnings. With ``displacement`` or
    ``target_velocity`` (and ``max_velocity``, ``max_acceleration``, ``max_jerk``), ``recommended`` is the
    request, ready to POST to its endpoint, of the design that settles first among those whose returned 5 %
    band covers the lowest mode's interval: time-optimal (robust over the interval, and nominal), every
    catalogue shaper, STAP with frequency_uncertainty, damped harmonic smoothers; ``recommendation.candidates``
    lists each with its settling time and band.

    **A printer's files** (``format``, told from the header by default): Klipper's accelerometer record
    (``#time,accel_x,accel_y,accel_z``, times printed to the microsecond: read as the uniform record they are) is
    fitted as above when it holds a free decay; a resonance test's record (a sweep) and Klipper's resonance CSV
    (``freq,psd_x,psd_y,psd_z,psd_xyz``) are answered from their spectrum (``spectrum``, ``peaks``). With
    ``target=klipper|reprapfirmware|marlin``, ``recommendation`` holds the input shaper to set in that firmware
    (``shaper``, ``max_acceleration``, ``remaining_vibration_percent``, ``smoothing``, ``firmware``), scored by
    Klipper's calibration criteria over the measured spectrum, never worse than Klipper's own pick by them
    (``klipper_calibration``), and robust over the frequency interval ``robust_over`` names."""
    if not _is_csv(request.headers.get("content-type")):
        if params.has_move() or request.query_params:
            name = next(iter(request.query_params), "displacement")
            raise InvalidParameter(
                name, request.query_params.get(name), "query parameters apply to text/csv bodies only"
            )
        try:
            record = IdentifyRequest.model_validate(body)
        except ValidationError as exc:
            raise RequestValidationError(
                [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False)]
            ) from None
        answer = await threads.run(identify_respond, record, settings, deadline_s=settings.thread_deadline_s)
        return NumpyJSONResponse(answer)
    text = _decode(body if isinstance(body, bytes) else str(body).encode())

    answer = await identify_csv(
        text,
        params,
        runner(settings, pool, threads),
        max_rows=settings.identify_max_rows,
        threads=threads,
        deadline_s=settings.thread_deadline_s,
    )
    return NumpyJSONResponse(answer)
