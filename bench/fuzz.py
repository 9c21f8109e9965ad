"""A long fuzzing run of every operation: schemathesis cases (valid and invalid) through the app and its pool.

    python bench/fuzz.py [--cases 2000] [--seed 0] [--only /v1/simulate]

For each operation: the cases run, the statuses answered, the server errors (a 5xx other than a declared
504 solve-timeout) and the failed checks (undeclared status or content type, a body not matching its
schema, schema-invalid input accepted), then the time taken. The settings are those of
tests/app/test_fuzz.py (small solve caps). Exits non-zero on any server error or failed check.

Memory of this process (the app's HTTP side, in-process over ASGI; the solver workers are its children): its RSS
once the pool is ready (start), after one call of every operation's OpenAPI example (warmed: tests/app/test_fuzz.py's
``warm_up``, the first-use cost of each family, stated separately), then per operation how much it grew during the
calls and between them (case generation: schemathesis and jsonschema_rs run in this process too), and at the end
the peak, its growth above the warmed figure against the test's bound, and the RSS left after ``malloc_trim``
(what of it was free heap glibc kept).

Then, per operation, the schema-valid cases (schemathesis' positive mode) answered 422, by problem type: an
``invalid-input`` there is a rule the OpenAPI does not express (a cross-field rule, a format inside a string),
listed with its most frequent field and rule; ``infeasible``, ``not-applicable`` and ``solver-failed`` depend on
the physics (limits no design meets, a family that does not apply), which no schema can say.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import ctypes
import http.client
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

import psutil

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from schemathesis import GenerationMode  # noqa: E402
from schemathesis.generation.meta import CaseMetadata  # noqa: E402
from schemathesis.python import asgi  # noqa: E402

from app.json_logs import APP_LOGGERS  # noqa: E402
from tests.app.openapi_examples import first_post_examples  # noqa: E402
from tests.app.server import readyz, serving  # noqa: E402
from tests.app.test_fuzz import (  # noqa: E402
    APP,
    CALL_TIMEOUT_S,
    CHECKS,
    COMPARE_BUDGET_S,
    FUZZ_SETTINGS,
    HTTP_PROCESS_GROWTH_BOUND,
    MIB,
    RESPONSE_BUDGET_S,
    WORKER_RSS_BOUND,
    RssSampler,
    schema,
    start_and_wait_ready,
    warm_up,
)

# Issue 23's target for the HTTP process's peak RSS over the whole run (a fresh process, first use included).
HTTP_PEAK_TARGET = 600 * MIB


class RssSteps:
    """Where this process's RSS grew: during the calls (the app: routing, validation, designs in its threads,
    the client) or between them (hypothesis and schemathesis generating the next case). Sums of the rises of
    RSS between two readings taken around every call; a fall is not subtracted (glibc keeps freed heap)."""

    def __init__(self, me: Any) -> None:
        self.me = me
        self.in_calls = 0
        self.between = 0
        self._last: int | None = None

    def before_call(self) -> None:
        rss = self.me.memory_info().rss
        if self._last is not None:
            self.between += max(0, rss - self._last)
        self._last = rss

    def after_call(self) -> None:
        rss = self.me.memory_info().rss
        assert self._last is not None
        self.in_calls += max(0, rss - self._last)
        self._last = rss


def trimmed_rss(me: Any) -> int | None:
    """This process's RSS after glibc's ``malloc_trim(0)`` has returned its free heap pages (None off glibc)."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        return None
    return int(me.memory_info().rss)


class ValidRefused:
    """Schema-valid cases answered 422: how many cases were schema-valid, the 422s by problem type, and the
    invalid-input ones by their first error's field and rule."""

    def __init__(self) -> None:
        self.valid = 0
        self.types: collections.Counter[str] = collections.Counter()
        self.rules: collections.Counter[str] = collections.Counter()

    def add(self, meta: CaseMetadata | None, response: Any) -> None:
        if meta is None or not meta.generation.mode.is_positive:
            return
        self.valid += 1
        if response.status_code != 422:
            return
        problem = response.json()
        slug = str(problem.get("type", "?")).removeprefix("/problems/")
        self.types[slug] += 1
        if slug == "invalid-input":
            first = (problem.get("errors") or [{}])[0]
            self.rules[f"{first.get('field')}: {str(first.get('rule'))[:90]}"] += 1

    def line(self) -> str:
        refused = sum(self.types.values())
        kinds = ", ".join(f"{k} {n}" for k, n in self.types.most_common())
        return f"schema-valid {self.valid}, answered 422: {refused}" + (f" ({kinds})" if kinds else "")


class Slowest:
    """The slowest answer of an operation, against its budget (tests/app/test_fuzz.py's)."""

    def __init__(self, path: str) -> None:
        self.budget_s = COMPARE_BUDGET_S if path.endswith("/compare") else RESPONSE_BUDGET_S
        self.worst_s = 0.0
        self.over = 0

    def add(self, elapsed_s: float) -> None:
        self.worst_s = max(self.worst_s, elapsed_s)
        self.over += elapsed_s > self.budget_s


def fuzz_operation(
    operation: Any, cases: int, seed: int, steps: RssSteps, base_url: str | None = None
) -> tuple[collections.Counter[int], list[str], float, ValidRefused, Slowest]:
    statuses: collections.Counter[int] = collections.Counter()
    slowest = Slowest(operation.path)
    failures: list[str] = []
    refused = ValidRefused()
    strategy = st.one_of(
        operation.as_strategy(generation_mode=GenerationMode.POSITIVE),
        operation.as_strategy(generation_mode=GenerationMode.NEGATIVE),
    )

    @settings(
        max_examples=cases,
        deadline=None,
        database=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(case=strategy)
    def run(case: Any) -> None:
        steps.before_call()
        started = time.perf_counter()
        try:
            response = case.call(base_url=base_url, timeout=CALL_TIMEOUT_S)
        except Exception as exc:  # in-process, the app's exception comes through: a server error, the run goes on
            steps.after_call()
            statuses[500] += 1
            failures.append(f"server exception {type(exc).__name__}: {str(exc)[:300]}")
            return
        slowest.add(time.perf_counter() - started)
        steps.after_call()
        statuses[response.status_code] += 1
        refused.add(case.meta, response)
        if response.status_code >= 500 and not (
            response.status_code == 504 and response.json().get("type") == "/problems/solve-timeout"
        ):
            failures.append(f"server error {response.status_code}: {response.text[:300]}")
        try:
            case.validate_response(response, checks=CHECKS)
        except (Exception, BaseExceptionGroup) as exc:  # every failed check is recorded, the run goes on
            failures.append(f"{type(exc).__name__}: {str(exc)[:300]}")

    start = time.perf_counter()
    seeded = run
    seeded._hypothesis_internal_use_seed = seed  # type: ignore[attr-defined]  # hypothesis.seed() for a plain call
    seeded()
    return statuses, failures, time.perf_counter() - start, refused, slowest


# FUZZ_SETTINGS as the server's environment (app.settings reads VIBFREE_*).
SERVER_ENV = {
    "VIBFREE_WORKERS": str(FUZZ_SETTINGS.workers),
    "VIBFREE_MAX_SAMPLES": str(FUZZ_SETTINGS.max_samples),
    "VIBFREE_MAX_BODY_BYTES": str(FUZZ_SETTINGS.max_body_bytes),
    "VIBFREE_SOLVE_TIME_LIMIT_S": str(FUZZ_SETTINGS.solve_time_limit_s),
    "VIBFREE_SOLVE_MAX_ITERATIONS": str(FUZZ_SETTINGS.solve_max_iterations),
    "VIBFREE_SOLVE_GRACE_S": str(FUZZ_SETTINGS.solve_grace_s),
}


class ServerSampler(RssSampler):
    """The RSS of a server's HTTP process (and its solver workers), read as it is: no fuzzer runs in it."""

    def __init__(self, pid: int) -> None:
        super().__init__()
        self.me = psutil.Process(pid)

    def held_rss(self) -> int:
        return int(self.me.memory_info().rss)


def warm_up_over_http(app: Any, port: int) -> None:
    """``warm_up`` against the server: every operation's first OpenAPI example once."""
    for path, body in first_post_examples(app.openapi()).items():
        connection = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
        connection.request("POST", path, json.dumps(body), {"content-type": "application/json"})
        connection.getresponse().read()
        connection.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", type=int, default=2000, help="cases per operation (default 2000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", default=None, help="only operations whose path contains this")
    parser.add_argument("--rules", type=int, default=5, help="most frequent invalid-input rules shown (default 5)")
    parser.add_argument(
        "--server",
        action="store_true",
        help="fuzz a real `vibfree serve` (one HTTP process, the same settings) over HTTP: the RSS is the server's "
        "alone, without the fuzzer's own heap",
    )
    args = parser.parse_args()
    with contextlib.ExitStack() as stack:
        return run_all(args, stack)


def run_all(args: argparse.Namespace, stack: contextlib.ExitStack) -> int:
    app = APP  # the test module's app and schema (importing it builds them): a second pair would be in the RSS
    # one access line per case would bury the figures: warnings and errors only (a 500 logs its traceback)
    for name in APP_LOGGERS:
        logging.getLogger(name).setLevel(logging.WARNING)
    base_url: str | None = None
    port = 0
    if args.server:
        port = stack.enter_context(serving(1, env=SERVER_ENV, extra=()))
        base_url = f"http://127.0.0.1:{port}"
        schema.app = None  # schemathesis then sends over HTTP (requests) to base_url
        sampler: RssSampler = ServerSampler(readyz(port)[1]["pid"])
        start_rss = sampler.me.memory_info().rss
        warm_up_over_http(app, port)
    else:
        start_and_wait_ready(app)
        sampler = RssSampler()
        start_rss = sampler.me.memory_info().rss
        warm_up(app)
    warmed_rss = sampler.me.memory_info().rss
    print(
        f"HTTP process: {start_rss / MIB:.0f} MiB at start (pool ready), {warmed_rss / MIB:.0f} MiB after every "
        f"operation's OpenAPI example once (first use {(warmed_rss - start_rss) / MIB:+.0f} MiB)"
    )
    sampler.start()
    steps = RssSteps(sampler.me)
    total_start = time.perf_counter()
    total_cases, total_failures, total_valid, total_refused = 0, 0, 0, 0
    print(f"{'operation':<40} {'cases':>6} {'time s':>8}  statuses; server errors and failed checks")
    for result in schema.get_all_operations():
        operation = result.ok()
        if args.only and args.only not in operation.path:
            continue
        in_calls, between = steps.in_calls, steps.between
        statuses, failures, elapsed, refused, slowest = fuzz_operation(
            operation, args.cases, args.seed, steps, base_url
        )
        if slowest.over:
            failures.append(f"{slowest.over} answers slower than the budget of {slowest.budget_s:g} s")
        n = sum(statuses.values())
        total_cases += n
        total_failures += len(failures)
        shown = ", ".join(f"{code}: {count}" for code, count in sorted(statuses.items()))
        print(f"{operation.method.upper() + ' ' + operation.path:<40} {n:>6} {elapsed:>8.1f}  {shown}; {len(failures)}")
        for failure in failures[:5]:
            print(f"    {failure}")
        total_valid += refused.valid
        total_refused += refused.types["invalid-input"]
        print(
            f"    slowest answer {slowest.worst_s:.2f} s (budget {slowest.budget_s:g} s); HTTP process "
            f"{sampler.me.memory_info().rss / MIB:.0f} MiB (peak {sampler.peak_rss / MIB:.0f}; rose "
            f"{(steps.in_calls - in_calls) / MIB:.0f} MiB in calls, {(steps.between - between) / MIB:.0f} between); "
            f"{refused.line()}"
        )
        for rule, count in refused.rules.most_common(args.rules):
            print(f"      {count:>4} {rule}")
        sys.stdout.flush()
    print(
        f"total: {total_cases} cases, {total_failures} server errors or failed checks, "
        f"{time.perf_counter() - total_start:.0f} s; {total_valid} schema-valid, {total_refused} of them answered "
        "422 invalid-input"
    )
    sampler.stopped.set()
    sampler.join(1.0)
    workers = readyz(port)[1] if args.server else app.state.pool.stats()
    end_rss = sampler.me.memory_info().rss
    trimmed = None if args.server else trimmed_rss(sampler.me)
    growth = sampler.peak_rss - warmed_rss
    growth_ok, peak_ok = growth <= HTTP_PROCESS_GROWTH_BOUND, sampler.peak_rss <= HTTP_PEAK_TARGET
    worst_worker = max(sampler.peak_children.values(), default=0)
    print(
        f"HTTP process: start {start_rss / MIB:.0f} MiB, first use {(warmed_rss - start_rss) / MIB:+.0f} MiB, "
        f"warmed {warmed_rss / MIB:.0f} MiB; peak {sampler.peak_rss / MIB:.0f} MiB = warmed + growth "
        f"{growth / MIB:.0f} MiB (bound {HTTP_PROCESS_GROWTH_BOUND / MIB:.0f}: {_met(growth_ok)}; "
        f"peak target {HTTP_PEAK_TARGET / MIB:.0f}: {_met(peak_ok)}); rose "
        f"{steps.in_calls / MIB:.0f} MiB in calls, {steps.between / MIB:.0f} MiB between them; held (read after "
        f"malloc_trim every 0.2 s, the fuzz test's bound) {sampler.peak_growth / MIB:.0f} MiB more; at the end "
        f"{end_rss / MIB:.0f} MiB" + (f", {trimmed / MIB:.0f} MiB after malloc_trim" if trimmed is not None else "")
    )
    print(
        "peak RSS of the solver workers "
        + ", ".join(f"{rss / MIB:.0f}" for rss in sampler.peak_children.values())
        + f" MiB ({len(sampler.peak_children)} processes seen; bound {WORKER_RSS_BOUND / MIB:.0f}: "
        f"{_met(worst_worker <= WORKER_RSS_BOUND)}); worker restarts {workers['restarts']}, of them "
        f"{workers['timeouts']} killed at a solve's deadline (a 504) and {workers['restarts'] - workers['timeouts']} "
        "died otherwise"
    )
    if not args.server:
        asgi.shutdown_lifespans()
    return 1 if total_failures else 0


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


if __name__ == "__main__":
    sys.exit(main())
