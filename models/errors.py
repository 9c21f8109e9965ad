"""The one error hierarchy of the service.

Every error the core raises is a ``DomainError`` that carries its problem type (a slug documented
under ``/problems/{slug}``), so that the HTTP layer maps them to problem+json in one place without
parsing messages. They are picklable across the worker-process boundary.

Proven infeasibility (``Infeasible``) is distinct from a family that does not apply
(``NotApplicable``), from a solver that stopped without an answer (``SolverFailed``), from a solve
that ran out of time (``SolverTimedOut``) and from a pool that cannot take work (``PoolUnavailable``).
"""

from __future__ import annotations

from typing import Any, ClassVar


class DomainError(Exception):
    """Base of every error the core raises on purpose."""

    problem_type: ClassVar[str] = "invalid-input"
    field: str | None = None


class InvalidParameter(DomainError, ValueError):
    """A value that breaks a physical or numerical rule (negative inertia, zeta >= 1, ...)."""

    problem_type = "invalid-input"
    field: str

    def __init__(self, field: str, value: Any, rule: str) -> None:
        self.field = field
        self.value = value
        self.rule = rule
        super().__init__(f"{field}={value!r}: {rule}")

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.field, self.value, self.rule))

    def under(self, prefix: str) -> InvalidParameter:
        """The same error with its field placed under a parent field (``plant`` -> ``plant.x``)."""
        return InvalidParameter(f"{prefix}.{self.field}" if prefix else self.field, self.value, self.rule)


class _Reasoned(DomainError, ValueError):
    """An error told by a reason in the user's terms, optionally about one field."""

    def __init__(self, reason: str, field: str | None = None) -> None:
        self.reason = reason
        self.field = field
        super().__init__(reason)

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.reason, self.field))


class Infeasible(_Reasoned):
    """Limits that no design can meet (proven); ``reason`` says why in the user's terms."""

    problem_type = "infeasible"


class NotApplicable(_Reasoned):
    """The family does not apply to this problem (a rest-to-velocity move for a rest-to-rest law, ...)."""

    problem_type = "not-applicable"


class SolverFailed(DomainError, RuntimeError):
    """The solver stopped without a usable optimum (infeasible iterate, iteration cap, numerical trouble).

    ``report`` is the solver's report (``optim.solver.SolverReport``) when there is one."""

    problem_type = "solver-failed"

    def __init__(self, report: Any, detail: str = "") -> None:
        self.report = report
        self.detail = detail
        status = getattr(report, "status", "unknown")
        iterations = getattr(report, "iterations", 0)
        super().__init__(detail or f"IPOPT stopped with status {status} after {iterations} iterations")

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self.report, self.detail))


class SolverTimedOut(SolverFailed):
    """The solve reached its wall-time cap (IPOPT's own, or the pool's deadline)."""

    problem_type = "solve-timeout"


class PoolUnavailable(DomainError, RuntimeError):
    """The solver pool is starting, restarting or broken: try again in ``retry_after_s``."""

    problem_type = "not-ready"

    def __init__(self, detail: str, retry_after_s: int = 5) -> None:
        self.retry_after_s = retry_after_s
        super().__init__(detail)

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (str(self), self.retry_after_s))
