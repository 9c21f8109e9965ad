"""Prometheus metrics of one app: requests, solves, the pool's and the threads' state, across HTTP processes."""

from __future__ import annotations

import contextlib
import logging
import os
import re
import threading
from collections.abc import Callable, Iterable, Mapping

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, PlatformCollector, ProcessCollector
from prometheus_client import multiprocess as prometheus_multiprocess
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector

log = logging.getLogger("app.observability")  # a failed scrape's log line names app.observability, as it did

LATENCY_BUCKETS_S = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0)


class PoolCollector(Collector):
    """The solver pool's state, read at scrape time from ``pool.stats()`` (skipped while it has none)."""

    GAUGES = (
        ("vibfree_pool_configured_workers", "workers", "Solver worker processes configured."),
        ("vibfree_pool_queue_depth", "queued", "Solves waiting for a worker."),
    )
    COUNTERS = (
        ("vibfree_pool_restarts", "restarts", "Worker processes replaced since start."),
        ("vibfree_pool_timeouts", "timeouts", "Solves killed at their deadline."),
        ("vibfree_pool_rejected", "rejected", "Solves refused by admission control."),
    )

    def __init__(self, pool: Callable[[], object | None]) -> None:
        self._pool = pool

    def collect(self) -> Iterable[Metric]:
        stats_of = getattr(self._pool(), "stats", None)
        if not callable(stats_of):
            return []
        try:
            stats: Mapping[str, int] = stats_of()
        except Exception:  # a scrape must not fail because the pool could not say
            log.exception("the solver pool's stats() failed")
            return []
        metrics: list[Metric] = []
        states = [s for s in ("ready", "busy", "starting") if s in stats]
        if states:
            workers = GaugeMetricFamily(
                "vibfree_pool_workers",
                "Solver worker processes by state (ready: warm, idle or busy).",
                labels=["state"],
            )
            for state in states:
                workers.add_metric([state], stats[state])
            metrics.append(workers)
        for name, key, doc in self.GAUGES:
            if key in stats:
                metrics.append(GaugeMetricFamily(name, doc, value=stats[key]))
        for name, key, doc in self.COUNTERS:
            if key in stats:
                metrics.append(CounterMetricFamily(name, doc, value=stats[key]))  # exposed as <name>_total
        return metrics


class ThreadsCollector(Collector):
    """The design threads' state (``runtime.threads.ThreadLane.stats()``), read at scrape time (skipped while none)."""

    GAUGES = (
        ("vibfree_threads_configured", "threads", "Design threads configured (closed-form designs and fits)."),
        ("vibfree_threads_running", "running", "Design threads computing."),
        ("vibfree_threads_queue_depth", "queued", "Designs waiting for a design thread."),
        ("vibfree_threads_held", "held", "Places reserved for requests' designs not yet submitted."),
        ("vibfree_threads_overrunning", "overrunning", "Design threads still computing past their deadline (504)."),
    )
    COUNTERS = (
        ("vibfree_threads_timeouts", "timeouts", "Designs answered 504 at their deadline."),
        ("vibfree_threads_rejected", "rejected", "Designs refused by admission control (503)."),
    )

    def __init__(self, lane: Callable[[], object | None]) -> None:
        self._lane = lane

    def collect(self) -> Iterable[Metric]:
        stats_of = getattr(self._lane(), "stats", None)
        if not callable(stats_of):
            return []
        try:
            stats: Mapping[str, int] = stats_of()
        except Exception:  # a scrape must not fail because the lane could not say
            log.exception("the design threads' stats() failed")
            return []
        metrics: list[Metric] = [
            GaugeMetricFamily(name, doc, value=stats[key]) for name, key, doc in self.GAUGES if key in stats
        ]
        metrics += [
            CounterMetricFamily(name, doc, value=stats[key]) for name, key, doc in self.COUNTERS if key in stats
        ]
        return metrics


class ThreadsGauges:
    """The design threads' state in the shared metrics directory (multiprocess mode), as ``PoolGauges``: gauges
    with this process's pid, counters summed. ``update(stats)`` is the lane's ``on_change`` callback (called
    from its threads: prometheus_client's values lock)."""

    def __init__(self, registry: CollectorRegistry) -> None:
        self.gauges = {
            key: Gauge(name, doc + " Per HTTP process.", multiprocess_mode="liveall", registry=registry)
            for name, key, doc in ThreadsCollector.GAUGES
        }
        self.counters = {
            key: Counter(name, doc + " Summed over the HTTP processes.", registry=registry)
            for name, key, doc in ThreadsCollector.COUNTERS
        }
        self._counted = dict.fromkeys(self.counters, 0)
        self._lock = threading.Lock()

    def update(self, stats: Mapping[str, int]) -> None:
        for key, gauge in self.gauges.items():
            gauge.set(stats.get(key, 0))
        with self._lock:
            for key, counter in self.counters.items():
                delta = stats.get(key, 0) - self._counted[key]
                if delta > 0:
                    counter.inc(delta)
                    self._counted[key] += delta


def multiprocess_dir() -> str | None:
    """The shared metrics directory of a multi-process server, or None (one process: in-memory metrics)."""
    return os.environ.get("PROMETHEUS_MULTIPROC_DIR") or None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, another user's
        return True
    return True


_LIVE_FILE = re.compile(r"gauge_live\w+?_(\d+)\.db")


def forget_dead_processes(path: str) -> list[int]:
    """``mark_process_dead`` for every process whose live-gauge files are in ``path`` but which is gone
    (a process killed without its shutdown); its counters stay in the sums. Returns their pids."""
    dead = set()
    with contextlib.suppress(OSError):
        for name in os.listdir(path):
            match = _LIVE_FILE.fullmatch(name)
            if match and not _alive(int(match.group(1))):
                dead.add(int(match.group(1)))
    for pid in dead:
        prometheus_multiprocess.mark_process_dead(pid, path)  # type: ignore[no-untyped-call]
    return sorted(dead)


class PoolGauges:
    """The pool's state in the shared metrics directory (multiprocess mode): gauges with this process's
    pid, counters summed over processes. ``update(stats)`` is the pool's ``on_change`` callback."""

    STATES = ("ready", "busy", "starting")

    def __init__(self, registry: CollectorRegistry) -> None:
        self.workers = Gauge(
            "vibfree_pool_workers",
            "Solver worker processes by state (ready: warm, idle or busy), per HTTP process.",
            ["state"],
            multiprocess_mode="liveall",
            registry=registry,
        )
        self.gauges = {
            key: Gauge(name, doc + " Per HTTP process.", multiprocess_mode="liveall", registry=registry)
            for name, key, doc in PoolCollector.GAUGES
        }
        self.counters = {
            key: Counter(name, doc + " Summed over the HTTP processes.", registry=registry)
            for name, key, doc in PoolCollector.COUNTERS
        }
        self._counted = dict.fromkeys(self.counters, 0)

    def update(self, stats: Mapping[str, int]) -> None:
        for state in self.STATES:
            self.workers.labels(state).set(stats.get(state, 0))
        for key, gauge in self.gauges.items():
            gauge.set(stats.get(key, 0))
        for key, counter in self.counters.items():
            delta = stats.get(key, 0) - self._counted[key]
            if delta > 0:
                counter.inc(delta)
                self._counted[key] += delta


def processes_state(path: str) -> dict[int, dict[str, int]]:
    """Each live HTTP process's pool state as the shared directory has it: pid -> {ready, busy, starting,
    queued, workers} (for /readyz: a probe lands on one process and answers for all)."""
    forget_dead_processes(path)
    registry = CollectorRegistry()
    prometheus_multiprocess.MultiProcessCollector(registry, path)  # type: ignore[no-untyped-call]
    out: dict[int, dict[str, int]] = {}
    keys = {"vibfree_pool_queue_depth": "queued", "vibfree_pool_configured_workers": "workers"}
    for metric in registry.collect():
        for sample in metric.samples:
            pid = sample.labels.get("pid")
            if pid is None:
                continue
            if sample.name == "vibfree_pool_workers":
                out.setdefault(int(pid), {})[sample.labels["state"]] = int(sample.value)
            elif sample.name in keys:
                out.setdefault(int(pid), {})[keys[sample.name]] = int(sample.value)
    return out


class ServiceMetrics:
    """One app's metrics, in a registry of its own (an app factory may run several times in a process).

    In multiprocess mode (``multiprocess_dir()``) the values also go to the shared directory, and
    ``scrape_registry()`` reads every process's; the pool's state is written by ``pool_gauges.update``."""

    def __init__(self, pool: Callable[[], object | None], threads: Callable[[], object | None] = lambda: None) -> None:
        self.multiprocess_dir = multiprocess_dir()
        self.registry = CollectorRegistry()
        self.requests = Counter(
            "vibfree_http_requests",
            "HTTP requests by method, route template (or 'unmatched') and status.",
            ["method", "route", "status"],
            registry=self.registry,
        )
        self.latency = Histogram(
            "vibfree_http_request_duration_seconds",
            "Time from the request to the last byte of the response, by route template.",
            ["route"],
            buckets=LATENCY_BUCKETS_S,
            registry=self.registry,
        )
        self.solves = Counter(
            "vibfree_solves",
            "Designs run by the service layer, by family and outcome ('ok' or the problem type).",
            ["family", "outcome"],
            registry=self.registry,
        )
        self.solve_duration = Histogram(
            "vibfree_solve_duration_seconds",
            "Wall time of one design in the service layer (waiting for a worker included), by family.",
            ["family"],
            buckets=LATENCY_BUCKETS_S,
            registry=self.registry,
        )
        self.pool_gauges: PoolGauges | None = None
        self.thread_gauges: ThreadsGauges | None = None
        if self.multiprocess_dir is None:
            self.registry.register(PoolCollector(pool))
            self.registry.register(ThreadsCollector(threads))
            ProcessCollector(registry=self.registry)
            PlatformCollector(registry=self.registry)
        else:  # custom collectors see only the answering process: the pool's state goes to the files
            self.pool_gauges = PoolGauges(self.registry)
            self.thread_gauges = ThreadsGauges(self.registry)

    def scrape_registry(self) -> CollectorRegistry:
        """What /metrics exposes: this app's registry, or in multiprocess mode every process's files."""
        if self.multiprocess_dir is None:
            return self.registry
        forget_dead_processes(self.multiprocess_dir)
        registry = CollectorRegistry()
        prometheus_multiprocess.MultiProcessCollector(registry, self.multiprocess_dir)  # type: ignore[no-untyped-call]
        return registry
