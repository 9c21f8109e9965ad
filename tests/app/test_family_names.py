"""One statement of the families' names (app.family_names): every other list of them agrees with it, in order."""

from __future__ import annotations

import typing

from app.families import BY_NAME
from app.family_names import NAMES, SLUGS, endpoint_of, name_of, slug_of
from app.schemas.compare import CompareOut
from app.schemas.registry import REQUEST_SCHEMAS
from app.schemas.sweeps import SweepIn
from optim.registry import FAMILIES


def test_the_schemas_the_families_and_the_enums_list_the_same_names_in_the_same_order() -> None:
    assert tuple(REQUEST_SCHEMAS) == NAMES
    assert tuple(FAMILIES) == NAMES
    assert typing.get_args(SweepIn.model_fields["family"].annotation) == SLUGS
    row = CompareOut.model_fields["rows"].annotation
    assert typing.get_args(typing.get_args(row)[0].model_fields["family"].annotation) == NAMES


def test_a_slug_is_the_name_with_hyphens_and_names_the_endpoint() -> None:
    for name, slug in zip(NAMES, SLUGS, strict=True):
        assert slug == name.replace("_", "-") and slug_of(name) == slug
        assert name_of(slug) == name == name_of(name)
        assert endpoint_of(name) == f"/v1/profiles/{slug}"


def test_the_warm_up_designs_the_solver_examples_of_the_family_table() -> None:
    """app.warmup reads the examples from the family table (no router): time-optimal's known_answer and jerk_limited
    (the compiled kernels of a held acceleration and of a held jerk), every pseudo-polynomial example (each an IPOPT
    solve) and the STAP examples that need IPOPT (the torque limit and method optimized; the closed forms need no
    worker)."""
    from app.settings import Settings
    from app.warmup import example_jobs

    names = [name for name, _, _ in example_jobs(Settings(workers=1))]
    assert names.count("time_optimal") == 2
    assert names.count("pseudo_polynomial") == len(BY_NAME["pseudo_polynomial"].examples) == 3
    assert names.count("stap") == 2 and set(names) == {"time_optimal", "pseudo_polynomial", "stap"}


def test_every_family_has_its_endpoint_in_the_openapi_and_its_slug_in_the_cli() -> None:
    """The routes' paths and the CLI's choices come from the names: the app serves exactly one profile endpoint per
    family (endpoint_of), and `vibfree design` offers exactly the slugs."""
    import argparse

    from app.main import create_app
    from vibfree import cli

    paths = {p for p in create_app().openapi()["paths"] if p.startswith("/v1/profiles/")}
    assert paths == {endpoint_of(name) for name in NAMES}
    commands = next(a for a in cli._parser()._actions if isinstance(a, argparse._SubParsersAction))
    design = commands.choices["design"]
    family = next(a for a in design._actions if a.dest == "family")
    assert tuple(family.choices) == SLUGS
