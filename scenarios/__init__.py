"""Scenarios: declarative descriptions of the standard cases, validated into typed objects."""

from scenarios.model import Scenario

__all__ = ["Scenario"]
