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


def road_user_sizes(scene):
    """(labels (N,), object indices (N,), sizes (N, 3)) of the scene's road users (mesh
    objects labelled vehicle, pedestrian or cyclist): each one's mesh box along its own
    axes, scale applied, as the ground truth boxes it. What ``priors.scene_types`` turns
    into the scene's types of road users."""
    import numpy as np

    from ..core.labels import ROAD_USERS

    wanted = {label_id(n) for n in ROAD_USERS}
    labels, sizes = [], []
    for obj in scene.objects:
        if obj.type != "MESH" or not len(obj.data.vertices):
            continue
        label = object_label(obj)
        if label not in wanted:
            continue
        corners = np.array([tuple(c) for c in obj.bound_box], np.float64)
        scale = np.abs(np.array(obj.matrix_world.to_scale(), np.float64))
        size = (corners.max(0) - corners.min(0)) * scale
        if (size > 0).all():
            labels.append(label)
            sizes.append(size)
    return (np.array(labels, np.int64), np.arange(len(labels)),
            np.array(sizes, np.float64).reshape(-1, 3))
