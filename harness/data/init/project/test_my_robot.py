"""The harness in your own test suite: the harness_run fixture (installed with the harness) runs a
scenario once per test session and returns its result."""


def test_my_model_and_method_pass_their_gates(harness_run):
    result = harness_run("scenario.toml")
    assert result.passed, [f"{g.name}: {g.value} (worst: {g.where})" for g in result.failed]
