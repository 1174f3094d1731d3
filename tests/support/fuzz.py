"""Hypothesis settings for the fuzz tests: a fixed, derandomized set of examples in `make test` (unit
tests must be deterministic), a long randomized campaign with `make soak` (STAGE_EMU_SOAK_EXAMPLES)."""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

SOAK_VARIABLE = "STAGE_EMU_SOAK_EXAMPLES"


def fuzz_settings(examples: int) -> settings:
    soak = os.environ.get(SOAK_VARIABLE)
    common = {"deadline": None, "database": None, "suppress_health_check": list(HealthCheck)}
    if soak:
        return settings(max_examples=int(soak), **common)
    return settings(max_examples=examples, derandomize=True, **common)
