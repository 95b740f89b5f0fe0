"""Live coverage: LiDARs rescanned as they are moved, and the region's metrics and map kept up to date (schedule: when; coverage: what)."""
