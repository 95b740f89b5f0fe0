"""The placement study: candidate mounts scanned once, sets of sensors searched, and its report."""
