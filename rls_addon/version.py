"""The software version, kept equal to ``blender_manifest.toml`` (a test checks)."""

VERSION = "0.1.0"
