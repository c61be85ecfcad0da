"""Hypothesis settings of the fuzz suites: seeded (derandomised), no deadline, no example
database, so every run draws the same cases and a failure names a seed to replay."""

from __future__ import annotations

from hypothesis import HealthCheck, settings


def seeded(max_examples: int) -> settings:
    """Settings drawing ``max_examples`` seeds, the same ones on every run."""
    return settings(max_examples=int(max_examples), derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow])
