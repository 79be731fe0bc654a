"""The runner: scenario, pipeline, gates, results.json."""
