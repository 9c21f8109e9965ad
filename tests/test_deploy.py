"""The Kubernetes manifest (deploy/kubernetes/vibfree.yaml): valid for the API server, and consistent with the
service it deploys (probes on routes that exist, settings that exist, the image's port, the shutdown budget)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import kubernetes_validate
import pytest
import yaml

from app.settings import Settings

ROOT = Path(__file__).resolve().parent.parent
MANIFEST = ROOT / "deploy" / "kubernetes" / "vibfree.yaml"
KUBERNETES_VERSION = "1.37.0"  # the newest schemas kubernetes-validate bundles (offline)
MIB = {"Mi": 1, "Gi": 1024}


def _documents() -> list[dict[str, Any]]:
    return [d for d in yaml.safe_load_all(MANIFEST.read_text()) if d]


def _by_name(kind: str, name: str) -> dict[str, Any]:
    (found,) = [d for d in _documents() if d["kind"] == kind and d["metadata"]["name"] == name]
    return found


def _container(deployment: str) -> dict[str, Any]:
    (container,) = _by_name("Deployment", deployment)["spec"]["template"]["spec"]["containers"]
    return container


def _mib(quantity: str) -> int:
    number, unit = re.fullmatch(r"(\d+)(Mi|Gi)", quantity).groups()  # type: ignore[union-attr]
    return int(number) * MIB[unit]


@pytest.mark.parametrize("index", range(len(_documents())))
def test_every_resource_is_valid_for_the_api_server(index: int) -> None:
    # Strict: an unknown or misspelt key (periodSecond) fails, as `kubectl apply --validate=strict` would.
    document = _documents()[index]
    kubernetes_validate.validate(document, KUBERNETES_VERSION, strict=True)


def test_probes_use_the_service_routes_on_the_image_port() -> None:
    from app.main import app
    from app.problems import api_routes

    paths = {path for path, route in api_routes(app) if "GET" in (route.methods or ())}
    container = _container("vibfree")
    assert container["readinessProbe"]["httpGet"]["path"] == "/readyz" in paths
    assert container["livenessProbe"]["httpGet"]["path"] == "/healthz" in paths
    (port,) = container["ports"]
    exposed = re.search(r"^EXPOSE (\d+)$", (ROOT / "Dockerfile").read_text(), re.M)
    assert exposed is not None and port["containerPort"] == int(exposed.group(1))
    service = _by_name("Service", "vibfree")
    assert service["spec"]["selector"] == _by_name("Deployment", "vibfree")["spec"]["selector"]["matchLabels"]


def test_every_vibfree_setting_named_exists() -> None:
    # A misspelt VIBFREE_ variable would be ignored by pydantic-settings (extra="ignore"), silently.
    fields = {f"VIBFREE_{name.upper()}" for name in Settings.model_fields}
    for deployment in ("vibfree", "vibfree-dask-worker"):
        for variable in _container(deployment).get("env", []):
            if variable["name"].startswith("VIBFREE_"):
                assert variable["name"] in fields, variable["name"]


def test_shutdown_budget_covers_the_graceful_shutdown() -> None:
    # uvicorn drains requests for --timeout-graceful-shutdown (the Makefile's SERVE_FLAGS); the pod must not be
    # killed before that plus its preStop pause.
    graceful = re.search(r"--timeout-graceful-shutdown (\d+)", (ROOT / "Makefile").read_text())
    assert graceful is not None
    spec = _by_name("Deployment", "vibfree")["spec"]["template"]["spec"]
    pause_s = int(_container("vibfree")["lifecycle"]["preStop"]["exec"]["command"][-1])
    assert spec["terminationGracePeriodSeconds"] >= int(graceful.group(1)) + pause_s


def test_dask_workers_run_one_thread_each() -> None:
    # IPOPT (MUMPS) is not thread-safe: a Dask worker with two threads could run two solves in one process.
    command = _container("vibfree-dask-worker")["command"]
    assert command[:2] == ["dask", "worker"]
    assert command[command.index("--nthreads") + 1] == "1"
    scheduler = _container("vibfree-dask-scheduler")["command"]
    port = scheduler[scheduler.index("--port") + 1]
    env = {v["name"]: v["value"] for v in _container("vibfree")["env"]}
    assert command[2] == env["VIBFREE_DASK_SCHEDULER"] == f"tcp://vibfree-dask-scheduler:{port}"


def test_memory_fits_the_measured_processes() -> None:
    # docs/benchmarks.md "Every core" (bench/worker_memory.py): supervisor and resource tracker 40 MiB, each HTTP
    # process 146 MiB, each warm solver worker 350 MiB typical and at most 450 MiB after 200 distinct plants (numba's
    # compiled kernels add ~100 MiB a worker). The request must hold the typical pod, the limit the pod at the bound,
    # or it is evicted or killed under load.
    supervisor_mib, http_mib, worker_typical_mib, worker_bound_mib = 40, 146, 350, 450
    container = _container("vibfree")
    env = {v["name"]: v["value"] for v in container["env"]}
    processes = int(env["VIBFREE_PROCESSES"])
    workers = processes * int(env["VIBFREE_WORKERS"])
    resources = container["resources"]
    assert _mib(resources["requests"]["memory"]) >= supervisor_mib + processes * http_mib + workers * worker_typical_mib
    assert _mib(resources["limits"]["memory"]) >= supervisor_mib + processes * http_mib + workers * worker_bound_mib
    # One HTTP process per requested core: the container sees the node's cores, so the count is given.
    assert processes == int(resources["requests"]["cpu"])
