"""A run spread over workers and cut short (Ctrl-C, a failed piece) removes what
killed or stopped workers left (a cloud without its sidecar, temporaries) only once
the cluster is closed: a write still under way on a worker could otherwise write a
sidecar after its cloud was removed, leaving a sidecar without its cloud (seen in
tests/cli/test_batch_cli.py::test_ctrl_c_stops_cleanly with two workers)."""

import types
from contextlib import contextmanager

import pytest

from rls_addon.commands import distribute


def test_leftovers_are_removed_after_the_cluster_is_closed(monkeypatch):
    events = []

    @contextmanager
    def cluster_client(workers, scheduler=None):
        events.append("cluster up")
        try:
            yield types.SimpleNamespace(scheduler_info=lambda: {"workers": {"a": 0, "b": 0}})
        finally:
            events.append("cluster closed")

    def run_tasks(client, calls, on_result):
        events.append("pieces handed out")
        raise KeyboardInterrupt

    monkeypatch.setattr(distribute, "cluster_client", cluster_client)
    monkeypatch.setattr(distribute, "run_tasks", run_tasks)
    monkeypatch.setattr(distribute, "remove_temporaries", lambda run: events.append("cleanup"))
    writer = types.SimpleNamespace(shardable=True, overwrite=True, resume=False)
    run = types.SimpleNamespace(sensors=[], frames=[1], total=1, writer=writer,
                                pieces=lambda count, by_sensor: [([], [1])],
                                still_sensors=set)
    args = types.SimpleNamespace(workers="2", scheduler=None, prepare_blender=None)
    with pytest.raises(KeyboardInterrupt):
        distribute.run_scan(args, run, "scene.blend")
    assert events == ["cluster up", "pieces handed out", "cluster closed", "cleanup"]
