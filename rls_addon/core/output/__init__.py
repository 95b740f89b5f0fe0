"""The output: point-cloud files, dataset layouts, ground-truth boxes and pictures of clouds."""
