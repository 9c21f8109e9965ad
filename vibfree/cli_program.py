"""``vibfree program``: a machine program (POST /v1/programs), in-process or against a running server."""

from __future__ import annotations

import argparse
from typing import Any

import orjson

from vibfree.cli_io import in_process, post, read, summary_stream, write
from vibfree.summaries import program_summary


def add_program_command(commands: Any) -> None:
    program = commands.add_parser(
        "program", help="a machine program: several axes, a cycle of moves between stops (POST /v1/programs)"
    )
    program.add_argument("request", help="the program's body (axes, start, moves), a JSON file (- for stdin)")
    program.add_argument("--csv", metavar="FILE", help="write the cam table, one column per axis (- for stdout)")
    program.add_argument("--json", metavar="FILE", help="write the whole answer as JSON (- for stdout)")
    program.add_argument("--url", help="a running service (e.g. http://127.0.0.1:8000); default: in-process")
    program.add_argument(
        "--processes", type=int, default=1, help="in-process: design the moves in this many worker processes at once"
    )
    program.set_defaults(run=run_program)


def run_program(args: argparse.Namespace) -> int:
    request = read(args.request)
    if args.url:
        answer = orjson.loads(post(args.url, "/v1/programs", request))
        csv = post(args.url, "/v1/programs", request, {"format": "csv"}).decode() if args.csv else None
    else:
        from vibfree.api import program

        done = in_process(lambda: program(request, processes=args.processes))
        answer = orjson.loads(orjson.dumps(done.answer, option=orjson.OPT_SERIALIZE_NUMPY))
        csv = done.csv() if args.csv else None
    print(program_summary(answer), file=summary_stream(args.json, args.csv))
    write(args.json, orjson.dumps(answer, option=orjson.OPT_INDENT_2).decode() + "\n")
    if csv is not None:
        write(args.csv, csv)
    return 0
