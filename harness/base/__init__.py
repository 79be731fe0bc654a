"""Foundation: errors and TOML reading, the plugin doors, workers, progress, the built-in data."""
