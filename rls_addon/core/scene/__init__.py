"""The scene: the interface through which the core asks about a scene, instances, world-space geometry and motion tracks."""
