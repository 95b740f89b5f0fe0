"""Semantic labels of Blender objects: custom property, else collection name."""

from ..core.labels import label_id, match_label

LABEL_PROPERTY = "rls_label"


def object_label(obj, parent=None):
    """Label id of ``obj``: its ``rls_label`` property (name or id), else that of the
    instancing parent, else the first of its collections whose name names a class
    (e.g. 'Road', 'Sidewalks', 'Buildings'), else 0 (unlabeled)."""
    for o in (obj, parent):
        if o is not None and LABEL_PROPERTY in o:
            return label_id(o[LABEL_PROPERTY])
    for o in (obj, parent):
        if o is None:
            continue
        for coll in o.users_collection:
            found = match_label(coll.name)
            if found is not None:
                return found
    return 0
