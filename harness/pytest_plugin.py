"""pytest plugin (entry point `pytest11`): the `harness_run` fixture, for a user's own test suite.

    def test_my_arm(harness_run):
        result = harness_run("arm.toml")      # relative to the test file's folder, or absolute
        assert result.passed, result.failed

The callable runs a scenario through the whole pipeline (harness.api.run) and returns its Result;
each scenario runs once per test session, however many tests ask for it.
"""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def _harness_results() -> dict:
    return {}


@pytest.fixture
def harness_run(request: pytest.FixtureRequest, _harness_results: dict):
    from harness.api import run

    folder = Path(request.path).parent

    def _run(scenario: str | Path):
        path = Path(scenario)
        if not path.is_absolute():
            path = folder / path
        key = path.resolve()
        if key not in _harness_results:
            _harness_results[key] = run(path)
        return _harness_results[key]

    return _run
