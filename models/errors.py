"""Errors raised by the physics core.

They carry the offending field, its value and the rule it breaks, so that the HTTP layer can
turn them into a problem+json without parsing messages.
"""

from __future__ import annotations

from typing import Any


class InvalidParameter(ValueError):
    """A value that breaks a physical or numerical rule (negative inertia, zeta >= 1, ...)."""

    def __init__(self, field: str, value: Any, rule: str) -> None:
        self.field = field
        self.value = value
        self.rule = rule
        super().__init__(f"{field}={value!r}: {rule}")

    def __reduce__(self) -> tuple:  # picklable across the worker-process boundary
        return (type(self), (self.field, self.value, self.rule))

    def under(self, prefix: str) -> InvalidParameter:
        """The same error with its field placed under a parent field (``plant`` -> ``plant.x``)."""
        return InvalidParameter(f"{prefix}.{self.field}" if prefix else self.field, self.value, self.rule)


class Infeasible(ValueError):
    """Limits that no design can meet; ``reason`` says why in the user's terms."""

    def __init__(self, reason: str, field: str | None = None) -> None:
        self.reason = reason
        self.field = field
        super().__init__(reason)

    def __reduce__(self) -> tuple:
        return (type(self), (self.reason, self.field))
