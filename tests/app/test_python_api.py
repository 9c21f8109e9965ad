"""The Python API and the CLI (issue 14): the service's pipeline in-process, the same answers as over HTTP."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import orjson
import pandas as pd
import pytest

import vibfree
from bench.time_optimal_batch import without_times
from tests import aio
from tests.app.conftest import TEST_SETTINGS
from vibfree import cli, summaries

ROOT = Path(__file__).resolve().parents[2]
STAP = {
    "plant": {"kind": "mode", "natural_frequency_hz": 40.0},
    "target_velocity": 150.0,
    "limits": {"max_acceleration": 1000.0},
    "sensitivity": {"min_ratio": 0.5, "max_ratio": 1.5, "count": 201},
}


def _numbers(body):
    return orjson.loads(orjson.dumps(body, option=orjson.OPT_SERIALIZE_NUMPY))


def test_synthesize_many_answers_each_move_in_order_and_keeps_a_refusal_in_its_place():
    # A batch as a machine plans its cycle: each answer is synthesize's own (the same bytes), a refused move is
    # its VibfreeError (the problem+json synthesize raises) and does not lose the others.
    moves = [dict(STAP, target_velocity=v) for v in (150.0, 100.0)]
    bad = dict(STAP, limits={"max_acceleration": -1.0})
    designs = vibfree.synthesize_many("stap", [moves[0], bad, moves[1]], settings=TEST_SETTINGS)
    assert [type(d).__name__ for d in designs] == ["Synthesis", "VibfreeError", "Synthesis"]
    for design, move in zip((designs[0], designs[2]), moves, strict=True):
        assert isinstance(design, vibfree.Synthesis)
        assert design.json() == vibfree.synthesize("stap", move, settings=TEST_SETTINGS).json()
    with pytest.raises(vibfree.VibfreeError) as refused:
        vibfree.synthesize("stap", bad, settings=TEST_SETTINGS)
    assert isinstance(designs[1], vibfree.VibfreeError) and designs[1].problem == refused.value.problem


def test_a_batch_on_two_processes_gives_the_serial_answers_in_order():
    # Chunks of consecutive moves on worker processes (vibfree.batch; one move a chunk here, 3 moves on 2
    # processes): each answer is the serial batch's, less its wall times, a refusal in its place. The time-optimal
    # moves' solve_time_s differ from run to run, so they are compared without them.
    mode = {"kind": "mode", "natural_frequency_hz": 40.0}
    moves = [
        {"plant": mode, "displacement": d, "limits": {"max_velocity": 5.0, "max_acceleration": 10.0}}
        for d in (0.12, 0.3)
    ]
    batch = [moves[0], dict(moves[0], displacement=0.0), moves[1]]
    serial = vibfree.synthesize_many("time-optimal", batch, settings=TEST_SETTINGS)
    parallel = vibfree.synthesize_many("time-optimal", batch, settings=TEST_SETTINGS, processes=2)
    assert [type(d).__name__ for d in parallel] == ["Synthesis", "VibfreeError", "Synthesis"]
    assert parallel[1].problem == serial[1].problem and parallel[1].status == 422
    for one, two in zip((serial[0], serial[2]), (parallel[0], parallel[2]), strict=True):
        dumped = [orjson.dumps(without_times(d.answer), option=orjson.OPT_SERIALIZE_NUMPY) for d in (one, two)]
        assert dumped[0] == dumped[1]
        assert one.csv() == two.csv()  # the result came back whole: the cam table too
    for processes in (0, (os.cpu_count() or 1) + 1):  # none, or more than the cores: refused, naming the field
        with pytest.raises(vibfree.VibfreeError) as refused:
            vibfree.synthesize_many("time-optimal", batch, processes=processes)
        assert refused.value.problem["field"] == "processes" and refused.value.status == 422


def test_a_program_on_two_processes_gives_the_in_process_answer() -> None:
    # The straight-line example's moves designed on two worker processes (vibfree.batch.ProcessesExecutor) and here
    # one after the other: the same answer, every number but the reported wall times, and the same cam table.
    from app.examples.programs import EXAMPLES

    body = EXAMPLES["straight_line"]["value"]
    here = vibfree.program(body, settings=TEST_SETTINGS)
    parallel = vibfree.program(body, settings=TEST_SETTINGS, processes=2)
    dumped = [
        re.sub(rb'"solve_time_s":[^,}]+', b"", orjson.dumps(a.answer, option=orjson.OPT_SERIALIZE_NUMPY))
        for a in (here, parallel)
    ]
    assert dumped[0] == dumped[1] and here.csv() == parallel.csv()
    with pytest.raises(vibfree.VibfreeError) as refused:
        vibfree.program(body, processes=(os.cpu_count() or 1) + 1)
    assert refused.value.problem["field"] == "processes" and refused.value.status == 422


def test_synthesize_gives_the_endpoints_answer_and_csv_byte_for_byte(client):
    # The same schemas, service layer and CSV writer: in-process and over HTTP agree exactly.
    design = vibfree.synthesize("stap", STAP, settings=TEST_SETTINGS)
    assert _numbers(design.answer) == client.post("/v1/profiles/stap", json=STAP).json()
    over_http = client.post("/v1/profiles/stap", json=STAP, params={"format": "csv", "columns": "all"}).text
    assert design.csv(columns=["all"]) == over_http
    # Cusimano Sec. 3: t_a = 0.175 s (eq. 61) for k_j = 1 at 40 Hz and a_Max = 1000 rad/s^2
    assert design.answer["design"]["acceleration_time_s"] == pytest.approx(0.175, rel=1e-12)


def test_synthesize_raises_the_services_problem(client):
    bad = {**STAP, "plant": {"kind": "mode", "natural_frequency_hz": -4.0}}
    with pytest.raises(vibfree.VibfreeError) as caught:
        vibfree.synthesize("stap", bad, settings=TEST_SETTINGS)
    assert caught.value.status == 422
    assert caught.value.problem == client.post("/v1/profiles/stap", json=bad).json()
    with pytest.raises(vibfree.VibfreeError) as caught:  # a refusal of the pipeline, not of the schema
        vibfree.synthesize("smoother", STAP, settings=TEST_SETTINGS)  # smoothers need a rest-to-rest move
    assert caught.value.problem["type"] == "/problems/not-applicable"
    assert caught.value.problem == client.post("/v1/profiles/smoother", json=STAP).json()
    with pytest.raises(vibfree.VibfreeError, match="no family"):
        vibfree.synthesize("bang-bang", STAP)


def test_compare_in_process_equals_the_endpoint(client):
    body = {**STAP, "families": ["stap", "input_shaped"]}
    assert _numbers(vibfree.compare(body, settings=TEST_SETTINGS)) == client.post("/v1/compare", json=body).json()


def _vibfree() -> list[str]:
    script = shutil.which("vibfree", path=str(Path(sys.executable).parent)) or shutil.which("vibfree")
    if script is None:
        if os.environ.get("CI"):
            raise AssertionError("the vibfree console script is not installed (pyproject [project.scripts])")
        pytest.skip("the vibfree console script is not installed (pip install -e .)")
    return [script]


def test_console_script_help_lists_the_commands():
    out = subprocess.run([*_vibfree(), "--help"], capture_output=True, text=True, check=True).stdout
    for command in ("design", "compare", "identify", "serve"):
        assert re.search(rf"^\s+{command}\s", out, re.MULTILINE), command


def test_console_script_designs_without_a_server(tmp_path):
    request = tmp_path / "request.json"
    request.write_bytes(orjson.dumps(STAP))
    out = tmp_path / "out.csv"
    run = subprocess.run(
        [*_vibfree(), "design", "stap", str(request), "--csv", str(out), "--json", str(tmp_path / "a.json")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"},
    )
    assert run.returncode == 0, run.stderr
    assert "settling  0.175 s" in run.stdout and "band 5 %" in run.stdout
    frame = pd.read_csv(out)
    assert list(frame.columns) == ["time_s", "position", "velocity", "acceleration", "jerk"]
    answer = orjson.loads((tmp_path / "a.json").read_bytes())
    assert frame["velocity"].iloc[-1] == pytest.approx(150.0, rel=1e-12)
    assert answer["metrics"]["settling_time_s"] == pytest.approx(0.175, rel=1e-9)


def test_cli_refusal_prints_the_field_and_exits_1(tmp_path, capsys):
    request = tmp_path / "bad.json"
    request.write_bytes(orjson.dumps({**STAP, "plant": {"kind": "mode", "natural_frequency_hz": -4.0}}))
    assert cli.main(["design", "stap", str(request)]) == 1
    assert "plant.natural_frequency_hz" in capsys.readouterr().err
    request.write_text("{not json")
    assert cli.main(["design", "stap", str(request)]) == 2
    assert "not valid JSON" in capsys.readouterr().err


def test_cli_compare_prints_a_ranking(tmp_path, capsys):
    request = tmp_path / "compare.json"
    request.write_bytes(orjson.dumps({**STAP, "families": ["stap", "input_shaped"]}))
    assert cli.main(["compare", str(request), "--json", "-"]) == 0
    captured = capsys.readouterr()
    ranking = orjson.loads(captured.out)
    assert captured.err.splitlines()[0].split()[:2] == ["design", "settling"]
    assert ranking["rows"][0]["label"] in captured.err.splitlines()[1]
    settling = [row["settling_time_s"] for row in ranking["rows"] if row["settling_time_s"] is not None]
    assert settling == sorted(settling)


def test_vibfree_serve_uses_the_flags_of_make_serve():
    dry_run = subprocess.run(["make", "-n", "serve"], capture_output=True, text=True, check=True, cwd=ROOT).stdout
    (line,) = [line for line in dry_run.splitlines() if "uvicorn app.main:app" in line]
    words = shlex.split(line[line.index("uvicorn app.main:app") :])
    flags = words[words.index("--port") + 2 :]
    assert tuple(flags) == cli.SERVE_FLAGS


def test_summaries_of_a_never_settling_row_and_an_empty_band():
    assert summaries.band_text(None) == "none"
    assert "never" in summaries.compare_summary(
        {
            "rows": [
                {
                    "label": "x",
                    "settling_time_s": None,
                    "motion_time_s": 1.0,
                    "percentage_vibration": 50.0,
                    "band_5_percent": None,
                }
            ],
            "unavailable": [],
        }
    )


def test_cli_identify_prints_the_modes_and_the_recommended_request(tmp_path, capsys):
    # tests/optim/test_identification_modal's record: 23 Hz (zeta 0.03) and 61 Hz (zeta 0.05), noise std 0.02
    from tests.optim.test_identification_modal import accelerometer_record, to_csv

    record = tmp_path / "record.csv"
    record.write_text(to_csv(*accelerometer_record(seed=3)))
    argv = ["identify", str(record), "--displacement", "0.05", "--max-velocity", "0.5", "--max-acceleration", "5"]
    assert cli.main([*argv, "--json", str(tmp_path / "answer.json")]) == 0
    out = capsys.readouterr().out
    answer = orjson.loads((tmp_path / "answer.json").read_bytes())
    found = [m["natural_frequency_hz"] for m in answer["modes"]]
    assert found == pytest.approx([23.0, 61.0], rel=0.01)  # the acceptance: within 1 %
    assert out.startswith(f"mode {found[0]:.6g} Hz") and "recommended:" in out
    request = orjson.loads(out.splitlines()[-1])
    assert request == answer["recommended"]["request"]
    design = vibfree.synthesize(answer["recommended"]["endpoint"].rsplit("/", 1)[1], request)
    lo, hi = design.answer["sensitivity"]["band_5_percent"]  # the design's band covers the mode's 95 % interval
    interval = answer["recommended"]["frequency_ratio_interval"]
    assert lo <= interval[0] and interval[1] <= hi


def test_the_python_api_works_inside_a_running_event_loop():
    # A notebook or an async caller already runs a loop in this thread: asyncio.run would refuse to start.

    async def inside() -> float:
        return vibfree.synthesize("stap", STAP, settings=TEST_SETTINGS).answer["metrics"]["settling_time_s"]

    assert aio.run(inside()) == pytest.approx(0.175, rel=1e-9)


def test_the_old_name_of_the_request_schemas_still_works_with_a_warning():
    import vibfree
    from vibfree import api

    with pytest.warns(DeprecationWarning, match="REQUEST_SCHEMAS"):
        assert vibfree.FAMILIES is vibfree.REQUEST_SCHEMAS
    with pytest.warns(DeprecationWarning, match="REQUEST_SCHEMAS"):
        assert api.FAMILIES is api.REQUEST_SCHEMAS


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork is POSIX")
def test_a_forked_child_designs_on_a_loop_of_its_own():
    # The API keeps one event loop in a daemon thread (compare and sweeps run on it; a design runs in the caller's
    # thread); a child forked after it ran has the loop object but not the thread, so reusing it would wait forever.
    # The child must start its own (exit 0), within 60 s.

    body = {**STAP, "families": ["stap"]}
    vibfree.compare(body, settings=TEST_SETTINGS)
    pid = os.fork()
    if pid == 0:  # the child: a comparison and a design, then its exit status says whether they matched
        try:
            ranked = vibfree.compare(body, settings=TEST_SETTINGS)["rows"][0]["settling_time_s"]
            design = vibfree.synthesize("stap", STAP, settings=TEST_SETTINGS)
            settling = design.answer["metrics"]["settling_time_s"]
            os._exit(0 if round(settling, 3) == 0.175 and ranked == settling else 1)
        except BaseException:
            os._exit(2)
    assert _child_exit_code(pid, "the forked child's design did not finish in 60 s") == 0


def test_designs_from_several_threads_take_turns_and_answer_as_one_thread():
    # A design runs in its caller's thread (no hop to the API's loop); IPOPT is not thread-safe, so calls from
    # several threads must take turns (vibfree.api._TURN): four threads designing at once give the serial answers.
    from concurrent.futures import ThreadPoolExecutor

    from app.examples.pseudo_polynomial import EXAMPLES

    base = EXAMPLES["shortest_with_limits"]["value"]  # IPOPT searches the duration
    requests = [{**base, "displacement": d} for d in (6.0, 8.0, 10.0, 12.0)]

    def design(request: dict[str, Any]) -> bytes:
        answer = vibfree.synthesize("pseudo-polynomial", request, settings=TEST_SETTINGS).answer
        return orjson.dumps(without_times(answer), option=orjson.OPT_SERIALIZE_NUMPY)

    serial = [design(r) for r in requests]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(design, requests * 2))
    assert threaded == serial * 2


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork is POSIX")
def test_a_child_forked_while_the_turn_is_held_designs():
    # The API's turn (vibfree.api._TURN) is held for a whole call; a child forked meanwhile gets the lock locked with
    # no thread to release it, so it must make its own (os.register_at_fork): the child designs (exit 0) within 60 s.

    from vibfree import api

    with api._TURN:  # as another thread's design would hold it
        pid = os.fork()
        if pid == 0:
            try:
                design = vibfree.synthesize("stap", STAP, settings=TEST_SETTINGS)
                os._exit(0 if round(design.answer["metrics"]["settling_time_s"], 3) == 0.175 else 1)
            except BaseException:
                os._exit(2)
    assert _child_exit_code(pid, "the forked child waited for a turn no thread of its own held") == 0


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="setitimer is POSIX")
def test_a_call_interrupted_while_its_coroutine_runs_keeps_the_turn_until_it_ends():
    # Ctrl-C in the caller of compare or sweep ends the wait, not the coroutine on the API's loop thread (IPOPT
    # there cannot be stopped): the turn is released when the coroutine ends, so a design from this thread waits for
    # it instead of solving beside it.
    import threading
    import time

    from vibfree import api

    done = threading.Event()

    async def solving() -> int:
        time.sleep(1.0)  # a synchronous solve on the loop thread
        done.set()
        return 1

    async def design() -> bool:
        return done.is_set()

    def interrupt(*_: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.2)
        with pytest.raises(KeyboardInterrupt):
            api._run(solving())
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert api._run_inline(design())  # it ran only once the interrupted call's coroutine had ended


def _child_exit_code(pid: int, timeout_message: str, timeout_s: float = 60.0) -> int:
    """The forked child's exit code; the test fails with ``timeout_message`` (the child killed) past ``timeout_s``."""
    import time

    deadline = time.monotonic() + timeout_s
    while (done := os.waitpid(pid, os.WNOHANG))[0] == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    if done[0] == 0:
        os.kill(pid, 9)
        os.waitpid(pid, 0)
        pytest.fail(timeout_message)
    return os.waitstatus_to_exitcode(done[1])
