"""A scene source with some objects hidden: the same scene, with every object of the
given labels left out of what the core reads. What a background sweep scans (the scene
without its road users, as a deployed roadside unit sees the junction when it is empty)."""

from .source import SceneRead


class WithoutLabels:
    """``source`` (a ``SceneSource``) without the objects whose label is in
    ``label_ids``; everything else is asked of ``source``. ``hidden`` holds the names of
    the objects left out of the reads so far."""

    def __init__(self, source, label_ids):
        self._source = source
        self.label_ids = frozenset(int(i) for i in label_ids)
        self.hidden = set()

    def __getattr__(self, name):
        return getattr(self._source, name)

    def read(self, centre, max_range, exclude):
        got = self._source.read(centre, max_range, exclude)
        kept = [i for i in got.instances if i.label not in self.label_ids]
        self.hidden.update(i.key for i in got.instances if i.label in self.label_ids)
        stats = dict(got.stats, hidden_road_users=len(got.instances) - len(kept))
        return SceneRead(kept, got.materials, stats)
