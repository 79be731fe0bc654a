"""A user's own test suite: the harness_run fixture (installed with harness) runs a scenario."""


def test_my_arm_agrees_with_the_reference_engines(harness_run):
    result = harness_run("arm.toml")
    assert result.passed, [(g.name, g.value) for g in result.failed]
