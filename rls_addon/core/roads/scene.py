"""``rls scene from-net`` as one core entry point: a SUMO network read, planned and
built into a scene by a builder that is handed in (Blender's: ``blender.roads``), with
progress from the first second. The command line and the UI's *Import SUMO network*
call ``scene_from_net`` with one ``FromNetSettings``.

The order keeps bad input cheap and nothing half-written: the output is checked, the
network read and planned (every refusal of ``network`` and ``layout``) before the
builder is made (Blender loads there), and the scene is saved (atomically, by the
builder) only when it is complete.
"""

import os
import time
from dataclasses import dataclass
from typing import Protocol

from ..errors import OutputError
from ..progress import EVERY_S, QUIET_S, Throttled
from .layout import build_layout
from .network import read_network



class Heartbeat:
    """Progress while one long call runs (sumolib's read): the stage is said once
    ``QUIET_S`` has passed (so an input refused at once gets one error line, no
    progress), then every ``PROGRESS_EVERY_S`` how long it has run; stops on exit."""

    def __init__(self, say, quiet=QUIET_S, every=EVERY_S):
        import threading

        self.say, self.quiet, self.every = say, quiet, every
        self.t0 = time.perf_counter()
        self.stage, self.said, self.pending = None, False, []
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._beat, daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()

    def tell(self, text, stage=None):
        """Say ``text`` (now, once ``quiet`` has passed; else when it passes)."""
        with self._lock:
            self.stage = stage
            if self.said:
                self.say(text)
            else:
                self.pending.append(text)

    def _beat(self):
        while not self._stop.wait(0.1):
            with self._lock:
                now = time.perf_counter() - self.t0
                if not self.said and now >= self.quiet:
                    self.said = True
                    for text in self.pending:
                        self.say(text)
                    self.pending, self.last = [], now
                elif self.said and self.stage and now - self.last >= self.every:
                    self.last = now
                    self.say(f"{self.stage}: {now:.0f} s so far")


@dataclass(frozen=True)
class FromNetSettings:
    net: str                      # the SUMO network (.net.xml)
    out: str | None = None        # the .blend to write; None: build into the open scene
    junction: str | None = None   # None: the default (layout.choose_junction)
    origin: str = "net"           # layout.ORIGINS
    overwrite: bool = False


class RoadSceneBuilder(Protocol):
    def build(self, layout, say, tiles) -> dict:
        """Fill the scene with ``layout``'s objects; ``say(text)`` the stages,
        ``tiles(done, total, seconds_left)`` the triangulation's tiles; a summary."""

    def save(self, out: str, overwrite: bool) -> None:
        """Write the scene to ``out``, whole or not at all."""


def check_out(out, overwrite):
    """``OutputError`` for an ``out`` that exists (without ``overwrite``) or whose
    folder does not."""
    if out is None:
        return
    if os.path.exists(out) and not overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")
    if not os.path.isdir(os.path.dirname(out)):
        raise OutputError(f"cannot write {out}: folder {os.path.dirname(out)} does not exist")


def tile_progress(say):
    """A ``tiles(done, total, seconds_left)`` that says where the triangulation is, at
    most every ``progress.EVERY_S`` seconds (and at its end)."""
    tell = Throttled(say, quiet=0.0)

    def tiles(done, total, left):
        tell(f"triangulating: tile {done} of {total}, about {left:.0f} s left",
             final=done == total)
    return tiles


def scene_from_net(settings, make_builder, say=None):
    """Build the scene of ``settings`` with the builder ``make_builder()`` returns
    (called once the network is read and planned); returns the summary dict."""
    say = say or (lambda text: None)
    t0 = time.perf_counter()
    out = None if settings.out is None else os.path.abspath(settings.out)
    check_out(out, settings.overwrite)
    size = os.path.getsize(settings.net) / 1e6 if os.path.isfile(settings.net) else 0.0
    with Heartbeat(say) as beat:
        beat.tell(f"reading {settings.net} ({size:.1f} MB) with sumolib", "reading")
        net = read_network(settings.net)
        beat.tell(f"{len(net.lanes)} lanes, {len(net.junctions)} junctions read in "
                  f"{time.perf_counter() - t0:.1f} s; planning the surfaces", "planning")
        layout = build_layout(net, settings.junction, settings.origin)
        del net  # sumolib's objects are not needed past the plan
    for notice in layout.notices:
        say(notice)
    say(f"{len(layout.pieces)} pieces at junction {layout.junction.id} planned in "
        f"{time.perf_counter() - t0:.1f} s; starting Blender")
    builder = make_builder()
    info = builder.build(layout, say, tile_progress(say))
    if out is not None:
        say(f"writing {out}")
        builder.save(out, settings.overwrite)
        info["scene"] = out
    info.update(network=os.path.abspath(settings.net),
                seconds=round(time.perf_counter() - t0, 3))
    return info
