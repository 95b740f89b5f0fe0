"""Live coverage (issue 39): how soon a moved LiDAR's preview, the InfraLOB's InfraD /
InfraNUC and the coverage map are updated, and how many scans a drag costs.

A Hesai Pandar64 on the sample intersection's north-east traffic-light pole (where a
study puts a LiDAR: 0.25 m above the pole, pitched 10 degrees down, facing the
junction), scene B as ``sample_scenes/make_scenes.py`` writes it with its 28 road
users (the LiDAR's own settings: exact motion, noise, dropout, ghosts), Live on with
the default debounce (a LiDAR rescanned once still for it) and the budget lifted so
that every move is measured (the UI's budget is the target). Blender's timer
is played by this process (the ``bpy`` module has no event loop): ``blender.live.tick``
is called when it asks to be, with real sleeps in between, so the debounce is waited
for as in the UI.

- ``moves``: single moves of 0.3 m, each to a place the LiDAR has not been (its static
  scene prepared around it anew, as a user's moves need), after one of each kind to
  warm up, three kinds interleaved (``_moves``: the road users' sampled sweep kept, as
  every move but the first after an edit; sampled anew, as that first one; Motion:
  Snapshot): the latency from the move (the depsgraph update that notes it included)
  to the update shown, its parts (the scan: the scene read from the depsgraph, the
  frame; the showing: preview, counts, map) and the states the sweep sampled from
  Blender. Target: within 150 ms.
- ``drags``: 20 steps of 0.1 m at 60 Hz and at 30 Hz (steps 16.7 and 33 ms apart, a
  drag in the viewport), the timer running between steps: the scans spent (what it
  needs: one, after the last step) and the latency after the last step.

Run in a child process (it registers RLS and its handlers):
``.venv/bin/python -m bench.live_costs [--quick]`` prints JSON, then markdown.
"""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench import standalone  # noqa: E402 - after the path above

TARGET_MS = 150.0


def _drive(live, until=None):
    """Play Blender's timer: call ``tick`` when it asks, until idle (or ``until``)."""
    while True:
        wait = live.tick()
        now = time.perf_counter()
        if wait is None:
            if until is not None and now < until:
                time.sleep(until - now)
            return
        if until is not None and now + wait >= until:
            time.sleep(max(0.0, until - now))
            return
        time.sleep(wait)


MODES = ("kept", "anew", "snapshot")


def _moves(bpy, live, session, lidar, n):
    """``n`` single moves of 0.3 m, each to a new place, in each of ``MODES``,
    interleaved (kept, anew, snapshot, kept, ...; the machine's load falls on all three
    alike), after one of each to warm up: {mode: [latency and its parts]}.

    - kept: the LiDAR's own settings (exact motion), the frame's sampled sweep of the
      road users kept since the last rescan (what a move costs);
    - anew: the same, the kept sweep forgotten before the move (what the first move
      after an edit of another object costs: the road users sampled again);
    - snapshot: Motion: Snapshot (the traffic frozen at the sweep's start)."""
    sched, kept = session.scheduler, session.sweeps
    out = {mode: [] for mode in MODES}
    for i in range(len(MODES) * (1 + n)):
        mode = MODES[i % len(MODES)]
        lidar.rls_lidar.motion = "snapshot" if mode == "snapshot" else "exact"
        if mode == "anew":
            kept.clear()
        misses = kept.misses
        # 0.3 m across and 5 cm along: never a place it has been (a place seen before
        # would find its static scene prepared already, ScanSession.prepared)
        lidar.location.x += 0.3 if i % 2 == 0 else -0.3
        lidar.location.y += 0.05
        t_move = time.perf_counter()
        bpy.context.view_layer.update()  # the handler notes it (what a move event does)
        _drive(live)
        latency = time.perf_counter() - t_move
        u = sched.updates[-1]
        if i >= len(MODES):
            out[mode].append({"latency_ms": 1000 * latency, "scan_ms": 1000 * u.scan_s,
                              "publish_ms": 1000 * u.publish_s, "scans": u.scans,
                              "states_read": kept.misses - misses})
    lidar.rls_lidar.motion = "exact"
    return out


def _child(quick):
    import bpy
    import numpy as np

    import rls_addon
    from rls_addon.blender import live
    from rls_addon.blender.scenes import build_scene
    from rls_addon.blender.scenes.build import mount_position

    rls_addon.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not hasattr(bpy.types.Object, "rls_lidar"):
        rls_addon.register()
    sc = bpy.context.scene
    build_scene("intersection", sc)
    x, y, z = mount_position(bpy.data.objects["TL NE"])
    sc.cursor.location = (x, y, z)
    bpy.ops.object.rls_add_lidar(preset="hesai_pandar64", show_fov=False)
    lidar = bpy.context.active_object
    lidar.rotation_euler = (0.0, np.radians(10.0), np.arctan2(-y, -x))
    bpy.context.view_layer.objects.active = bpy.data.objects["InfraLOB"]
    # measured against the target, not cut short by the fallback: a budget no update
    # reaches here (the UI's is the target, 150 ms)
    sc.rls_live.budget_ms = 60000.0
    t = time.perf_counter()
    assert bpy.ops.rls.live_coverage() == {"FINISHED"}
    first_s = time.perf_counter() - t
    session = live.session()
    sched = session.scheduler
    n_moves = 6 if quick else 15
    moves = _moves(bpy, live, session, lidar, n_moves)
    drags = []
    for hz in (60.0, 30.0):
        scans, superseded, updates = sched.scans, sched.superseded, len(sched.updates)
        step = 1.0 / hz
        t_next = time.perf_counter()
        for i in range(20):
            lidar.location.y += 0.1 if hz == 60.0 else -0.1  # (not back where it was)
            bpy.context.view_layer.update()
            t_last = time.perf_counter()
            t_next += step
            if i < 19:
                _drive(live, until=t_next)
        _drive(live)
        drags.append({"hz": hz, "steps": 20, "scans": sched.scans - scans,
                      "superseded": sched.superseded - superseded,
                      "updates": len(sched.updates) - updates,
                      "latency_ms": 1000 * (time.perf_counter() - t_last)})
    points = len(session.clouds[lidar.name])
    live.stop()
    return {"device": "hesai_pandar64", "scene": "sample intersection (scene B)",
            "points": points, "first_update_s": first_s,
            "debounce_ms": 1000 * sched.settings.debounce_s,
            "moves": moves, "drags": drags, "load_average": os.getloadavg()[0]}


def measure(quick=False):
    """Run the measurement in a child process; its numbers."""
    args = [sys.executable, "-m", "bench.live_costs", "--child"] + (["--quick"] if quick else [])
    proc = subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=1800,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    if proc.returncode != 0:
        raise RuntimeError(f"bench.live_costs failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _median(values):
    v = sorted(values)
    return v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])


def _row(label, moves):
    lat = [m["latency_ms"] for m in moves]
    within = sum(v <= TARGET_MS for v in lat)
    return (f"| {label} | {_median(lat):.0f} ms | {max(lat):.0f} ms | "
            f"{_median([m['scan_ms'] for m in moves]):.0f} ms | "
            f"{_median([m['publish_ms'] for m in moves]):.0f} ms | "
            f"{_median([m['states_read'] for m in moves]):.0f} | "
            f"{within} of {len(lat)} within {TARGET_MS:.0f} ms |")


ROWS = {"kept": "its own settings (exact motion), the road users' sampled sweep kept",
        "anew": "the same, the sweep sampled anew (the first move after another "
                "object's edit)",
        "snapshot": "Motion: Snapshot (the traffic frozen at the sweep's start)"}


def section(r):
    L = ["## Live coverage: a moved LiDAR's update (issue 39)\n",
         f"A {r['device']} on the {r['scene']}'s north-east traffic-light pole, its own "
         f"settings (exact motion through the 28 road users, noise, dropout, ghosts; "
         f"{r['points']:,} points a scan), Live on (rescanned once still for "
         f"{r['debounce_ms']:.0f} ms; `bench/live_costs.py`, Blender's timer played by the "
         f"bench with real sleeps; load average {r['load_average']:.1f}). Switching Live on "
         f"(the first scan prepares the scene) took {r['first_update_s'] * 1000:.0f} ms.\n",
         "| a move of 0.3 m -> update shown | median | slowest | of which the scan "
         "(the depsgraph read, the frame) | of which the showing (preview, counts, map) | "
         "states sampled from Blender | target |",
         "|---|---|---|---|---|---|---|",
         *[_row(f"{ROWS[mode]}, {len(r['moves'][mode])} moves", r["moves"][mode])
           for mode in MODES],
         "",
         "The three kinds of move are interleaved (one of each in turn), so the "
         "machine's load falls on them alike. "
         f"Each latency includes the {r['debounce_ms']:.0f} ms the LiDAR must be still.\n"]
    L += ["| drag of 20 steps | scans spent | superseded | updates shown | last step -> update |",
          "|---|---|---|---|---|"]
    for d in r["drags"]:
        L.append(f"| at {d['hz']:.0f} Hz | {d['scans']} (needs 1) | {d['superseded']} | "
                 f"{d['updates']} | {d['latency_ms']:.0f} ms |")
    L += ["", "In the UI an update whose work (scans and showing) is over the 150 ms budget "
          "twice in a row switches the scene to on demand (the panel says so, *Update "
          "Coverage* updates it); the bench lifts the budget to measure every move.", ""]
    return L


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--child" in argv:
        print(json.dumps(_child("--quick" in argv)))
        return None
    return standalone.main(__doc__, measure, section, argv)


if __name__ == "__main__":
    main()
