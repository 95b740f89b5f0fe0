"""The scan: settings, one frame of one sensor, the session that keeps what frames share, and the run over frames and sensors (with its Dask shards)."""
