"""LiDAR-relevant facts of Blender materials."""

from ..core.geometry import MaterialInfo

REFLECTIVITY_PROPERTY = "rls_reflectivity"
GLOSSY_PROPERTY = "rls_glossy"
GHOST_RATIO_PROPERTY = "rls_ghost_ratio"


def _principled(material):
    if material.use_nodes and material.node_tree:
        for node in material.node_tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                return node
    return None


def _luminance(rgb):
    r, g, b = rgb[:3]
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def material_info(material):
    """Reflectivity from the ``rls_reflectivity`` property, else the luminance of the
    Principled BSDF base colour (else the viewport diffuse colour)."""
    if REFLECTIVITY_PROPERTY in material:
        refl = float(material[REFLECTIVITY_PROPERTY])
    else:
        node = _principled(material)
        if node is not None:
            refl = _luminance(node.inputs["Base Color"].default_value)
        else:
            refl = _luminance(material.diffuse_color)
    glossy = bool(material.get(GLOSSY_PROPERTY, False))
    ratio = float(material.get(GHOST_RATIO_PROPERTY, 0.5))
    return MaterialInfo(material.name, min(max(refl, 0.0), 1.0), glossy, ratio)
