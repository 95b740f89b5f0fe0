"""The device: presets (validated TOML data), their schema, user presets, vendor angle tables and the scan patterns they generate."""
