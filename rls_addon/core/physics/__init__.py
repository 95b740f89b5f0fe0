"""The physics of a return: detection by the LiDAR equation, weather, beam footprints and echoes, ghosts, noise and dropout, and the per-hit stage that makes point records."""
