"""``vibfree``: design, compare, identify, sweep and program from the command line, in-process or against a server
(``--url``).

Each command prints a short summary for a person (stderr when the data itself goes to stdout) and writes the
answer as JSON (``--json FILE``, ``-`` for stdout) or the profile as CSV (``--csv FILE``). Exit status: 0 done,
1 the design was refused (the problem+json is printed), 2 bad usage or an unreadable file.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import orjson

from app.family_names import SLUGS
from vibfree.cli_io import Refused, in_process, post, post_lines, read, summary_stream, write
from vibfree.cli_program import add_program_command
from vibfree.summaries import compare_summary, design_summary, identify_summary

# The flags of ``make serve`` (docs/deployment.md says why each); tests check they match the Makefile's.
SERVE_FLAGS = (
    "--no-access-log",
    "--no-server-header",
    "--http",
    "h11",
    "--timeout-keep-alive",
    "5",
    "--h11-max-incomplete-event-size",
    "16384",
    "--timeout-graceful-shutdown",
    "30",
)
# One BLAS thread per process unless the caller says otherwise (the Makefile and the Dockerfile do the same): the
# service runs a process per core already, BLAS threads on top oversubscribe them (a 3x1 product took 13.6 ms with
# OpenBLAS's threads on the loaded machine, 0.47 ms without), and a solve's last bits depend on the thread count, so
# the pool's rows equal a Dask worker's (whose nanny sets the same) bit for bit.
SINGLE_THREADED_BLAS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
IDENTIFY_QUERY = ("displacement", "target_velocity", "max_velocity", "max_acceleration", "max_jerk", "target",
                  "format", "square_corner_velocity", "max_smoothing", "frequency_tolerance")  # fmt: skip
SWEEP_OPTIONS = {  # the resonance test's settings (a sweep's or a resonance CSV's excitation): Klipper's names
    "sweep_min_freq": "Hz: the resonance test's min_freq / FREQ_START (5)",
    "sweep_max_freq": "Hz: its max_freq / FREQ_END (135; z 100)",
    "sweep_hz_per_sec": "its hz_per_sec / HZ_PER_SEC (1)",
    "sweep_accel_per_hz": "mm/s^2 per Hz: its accel_per_hz (60; z 15)",
    "sweeping_accel": "mm/s^2: its sweeping_accel (400; z 50)",
    "sweeping_period": "s: its sweeping_period (1.2; 0 for none)",
}


def one_blas_thread() -> None:
    """Default this process's BLAS libraries to one thread, as ``vibfree serve`` and the image do for the workers
    (an explicit setting wins); effective only before numpy loads them. A design's last bits, and so which local
    optimum SLSQP reaches, depend on the thread count; with OpenBLAS's threads its small solves took 2-30 times
    longer whenever another process ran beside them."""
    for name in SINGLE_THREADED_BLAS:
        os.environ.setdefault(name, "1")


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        with _quiet_service_logs():
            return int(args.run(args))
    except Refused as exc:
        _print_problem(exc.problem)
        return 1
    except (OSError, ValueError) as exc:  # unreadable files, bad JSON, an unreachable server
        print(f"vibfree: {exc}", file=sys.stderr)
        return 2


@contextlib.contextmanager
def _quiet_service_logs() -> Iterator[None]:
    """The service's info lines (one per solve) are for servers: a person sees the summary, and warnings."""
    loggers = [logging.getLogger(name) for name in ("app", "optim", "runtime", "models")]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.WARNING)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels, strict=True):
            logger.setLevel(level)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="vibfree",
        description="Vibration-free motion profiles for elastic machines: the service's designs, in-process or "
        "against a running server (--url).",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    design = commands.add_parser("design", help="design one family's command (POST /v1/profiles/FAMILY)")
    design.add_argument("family", choices=SLUGS, help="the family")
    design.add_argument("request", help="the request body, a JSON file (- for stdin)")
    design.add_argument("--csv", metavar="FILE", help="write the profile as CSV (- for stdout)")
    design.add_argument("--columns", help="CSV columns, comma-separated (e.g. time_s,position,load_position; all)")
    design.add_argument("--comments", action="store_true", help="CSV: add # lines with units and metadata")
    _common(design)
    design.set_defaults(run=_design)

    compare = commands.add_parser("compare", help="every family side by side (POST /v1/compare)")
    compare.add_argument("request", help="the request body, a JSON file (- for stdin)")
    _common(compare)
    compare.set_defaults(run=_compare)

    identify = commands.add_parser(
        "identify", help="the modes of a recorded vibration and the recommended design (POST /v1/identify)"
    )
    identify.add_argument(
        "record",
        help="a CSV file: a header, a time_s column, one or more signal columns; or Klipper's accelerometer record "
        "(#time,accel_x,accel_y,accel_z) or resonance CSV (freq,psd_x,psd_y,psd_z,psd_xyz)",
    )
    identify.add_argument(
        "--target",
        choices=("klipper", "reprapfirmware", "marlin"),
        help="print the input shaper to set in this firmware (Klipper's [input_shaper] section, M593, M493)",
    )
    identify.add_argument("--format", choices=("auto", "generic", "klipper_raw", "klipper_psd", "rrf_accelerometer"))
    identify.add_argument("--square-corner-velocity", type=float, help="mm/s, for smoothing and max_accel (5)")
    identify.add_argument("--max-smoothing", type=float, help="mm: Klipper's max_smoothing (0.05 or more)")
    identify.add_argument(
        "--frequency-tolerance", type=float, help="make the shaper robust over f x [1 - tol, 1 + tol]"
    )
    for name, meaning in SWEEP_OPTIONS.items():
        identify.add_argument(f"--{name.replace('_', '-')}", type=float, help=meaning)
    move = identify.add_mutually_exclusive_group()
    move.add_argument("--displacement", type=float, help="the move to recommend a design for (rest-to-rest)")
    move.add_argument("--target-velocity", type=float, help="or the final speed (rest-to-velocity)")
    identify.add_argument("--max-velocity", type=float)
    identify.add_argument("--max-acceleration", type=float)
    identify.add_argument("--max-jerk", type=float)
    _common(identify)
    identify.set_defaults(run=_identify)

    sweep = commands.add_parser(
        "sweep",
        help="one family across a grid of requests, and whether the table may be interpolated (POST /v1/sweeps)",
    )
    sweep.add_argument("request", help="the sweep body (family, request, axes), a JSON file (- for stdin)")
    sweep.add_argument("--out", metavar="FILE", help="write one row per point: FILE.csv, FILE.parquet, or - (CSV)")
    sweep.add_argument("--url", help="a running service (e.g. http://127.0.0.1:8000); default: in-process")
    sweep.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    sweep.set_defaults(run=_sweep)

    add_program_command(commands)
    serve = commands.add_parser("serve", help="run the HTTP service (uvicorn, the flags of make serve)")
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=8000)
    serve.add_argument(
        "--proxy-headers",
        action="store_true",
        help="trust X-Forwarded-* from FORWARDED_ALLOW_IPS (uvicorn's flag; docs/deployment.md, reverse proxy)",
    )
    serve.add_argument(
        "--processes",
        type=int,
        help="HTTP processes, each with its solver pool (default VIBFREE_PROCESSES: one per core)",
    )
    serve.set_defaults(run=_serve)
    return parser


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", metavar="FILE", help="write the whole answer as JSON (- for stdout)")
    parser.add_argument("--url", help="a running service (e.g. http://127.0.0.1:8000); default: in-process")


# --- commands ----------------------------------------------------------------------------------


def _design(args: argparse.Namespace) -> int:
    request = read(args.request)
    columns = None if args.columns is None else [c.strip() for c in args.columns.split(",") if c.strip()]
    if args.url:
        path = f"/v1/profiles/{args.family}"
        answer = orjson.loads(post(args.url, path, request))
        csv = None
        if args.csv:
            query = {"format": "csv", **({"columns": ",".join(columns)} if columns else {})}
            if args.comments:
                query["comments"] = "true"
            csv = post(args.url, path, request, query).decode()
    else:
        from vibfree.api import synthesize

        synthesis = in_process(lambda: synthesize(args.family, request))
        answer = orjson.loads(synthesis.json())
        csv = None
        if args.csv:
            csv = in_process(lambda: synthesis.csv(columns=columns, comments=args.comments))
    out = summary_stream(args.json, args.csv)
    print(design_summary(args.family, answer), file=out)
    write(args.json, orjson.dumps(answer, option=orjson.OPT_INDENT_2).decode() + "\n")
    if csv is not None:
        write(args.csv, csv)
    return 0


def _compare(args: argparse.Namespace) -> int:
    request = read(args.request)
    if args.url:
        answer = orjson.loads(post(args.url, "/v1/compare", request))
    else:
        from vibfree.api import compare

        answer = orjson.loads(orjson.dumps(in_process(lambda: compare(request)), option=orjson.OPT_SERIALIZE_NUMPY))
    print(compare_summary(answer), file=summary_stream(args.json))
    write(args.json, orjson.dumps(answer, option=orjson.OPT_INDENT_2).decode() + "\n")
    return 0


def _identify(args: argparse.Namespace) -> int:
    record = Path(args.record).read_bytes()
    names = (*IDENTIFY_QUERY, *SWEEP_OPTIONS)
    query = {name: getattr(args, name) for name in names if getattr(args, name) is not None}
    if args.url:
        answer = orjson.loads(post(args.url, "/v1/identify", record, query, content_type="text/csv"))
    else:
        from vibfree.api import identify

        answer = in_process(lambda: identify(record, **query))
    print(identify_summary(answer), file=summary_stream(args.json))
    write(args.json, orjson.dumps(answer, option=orjson.OPT_INDENT_2 | orjson.OPT_SERIALIZE_NUMPY).decode() + "\n")
    return 0


class _NoBar:
    """Where tqdm (the cli extra) is not installed: keeps the total, draws nothing."""

    def __init__(self, total: int | None = None, **_: Any) -> None:
        self.total = total

    def __enter__(self) -> _NoBar:
        return self

    def __exit__(self, *_: object) -> None:
        return None

    def update(self, n: int = 1) -> None:
        return None


def _progress_bar(wanted: bool = True) -> Any:
    """tqdm, or a bar that draws nothing where the cli extra is missing (saying what to install, if a bar was
    wanted)."""
    try:
        from tqdm import tqdm
    except ModuleNotFoundError:
        if wanted:
            print("(no progress bar: pip install 'vibfree[cli]' for one)", file=sys.stderr)
        return _NoBar
    return tqdm


def _sweep(args: argparse.Namespace) -> int:
    tqdm = _progress_bar(wanted=not args.no_progress)
    from vibfree.sweep_table import flat_rows, summary_text, write_table

    request = read(args.request)
    lines: list[dict[str, Any]] = []
    # mininterval 0: every row redraws the bar (a handful a second at most), so its last state (100 %) is drawn even
    # when the last rows arrive within tqdm's default 0.1 s of each other (fast designs: certified ones take ms)
    with tqdm(
        total=_points(request), unit="point", file=sys.stderr, disable=args.no_progress, leave=False, mininterval=0
    ) as bar:

        def seen(line: dict[str, Any]) -> None:
            lines.append(line)
            if line.get("line") == "row":
                if bar.total is not None and line["index"] >= bar.total:
                    bar.total = line["index"] + 1  # a point refinement added
                bar.update(1)

        if args.url:
            for line in post_lines(args.url, "/v1/sweeps", request):
                seen(line)
        else:
            from vibfree.api import sweep

            in_process(lambda: sweep(request, on_line=seen))
    print(summary_text(lines), file=summary_stream(args.out))
    if args.out:
        write_table(args.out, flat_rows(lines))
    return 0


def _points(request: bytes) -> int | None:
    """The grid's size, for the progress bar (None where the body is not a sweep: the service says why)."""
    try:
        sizes = [
            len(a["values"]) if a.get("values") is not None else int(a["num"]) for a in orjson.loads(request)["axes"]
        ]
    except (KeyError, TypeError, ValueError):
        return None
    total = 1
    for size in sizes:
        total *= size
    return total


def serve_command(host: str, port: int, processes: int) -> list[str]:
    """The uvicorn command line of ``make serve``: ``processes`` HTTP processes under uvicorn's supervisor
    (it replaces one that dies), then the flags of SERVE_FLAGS."""
    head = [sys.executable, "-m", "uvicorn", "app.main:app", "--workers", str(processes)]
    return [*head, "--host", host, "--port", str(port), *SERVE_FLAGS]


def serve_environment(processes: int) -> dict[str, str]:
    """The server's environment: the process count for its settings (``/readyz`` expects that many) and a
    fresh, empty metrics directory for prometheus_client's multiprocess mode (set before any process
    imports it, as its documentation asks: https://prometheus.github.io/client_python/multiprocess/)."""
    import tempfile

    directory = tempfile.mkdtemp(prefix="vibfree-metrics-")
    blas = dict.fromkeys(SINGLE_THREADED_BLAS, "1")
    return {**blas, **os.environ, "VIBFREE_PROCESSES": str(processes), "PROMETHEUS_MULTIPROC_DIR": directory}


def serve_argv(argv: Sequence[str], processes: int) -> list[str]:
    """The uvicorn command line that ``vibfree serve <argv>`` runs with ``processes`` processes (what the
    Dockerfile's ``CMD`` starts: the tests check its flags through this)."""
    return _uvicorn_command(_parser().parse_args(["serve", *argv]), processes)


def _uvicorn_command(args: argparse.Namespace, processes: int) -> list[str]:
    return [*serve_command(args.host, args.port, processes), *(["--proxy-headers"] if args.proxy_headers else [])]


def _serve(args: argparse.Namespace) -> int:
    from app.settings import Settings

    processes = args.processes or Settings().processes
    if processes < 1:
        raise SystemExit("--processes must be at least 1")
    command = _uvicorn_command(args, processes)
    # Replaces this process: signals reach uvicorn's supervisor, which passes them to its processes.
    os.execve(sys.executable, command, serve_environment(processes))


# --- I/O ---------------------------------------------------------------------------------------


def _print_problem(problem: dict[str, Any]) -> None:
    print(
        f"vibfree: {problem.get('status', '')} {problem.get('title', 'refused')}: {problem.get('detail', '')}",
        file=sys.stderr,
    )
    for error in problem.get("errors") or []:
        print(f"  {error.get('field')}: {error.get('rule')} (got {error.get('value')!r})", file=sys.stderr)


if __name__ == "__main__":
    raise SystemExit(main())
