"""Metrics over a region of interest (the InfraLOB): InfraD, InfraNUC, the disks they count in, traffic visibility, polygons and density charts."""
