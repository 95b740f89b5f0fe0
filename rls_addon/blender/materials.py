"""LiDAR-relevant facts of Blender materials."""

from ..core.scene.geometry import MaterialInfo

REFLECTIVITY_PROPERTY = "rls_reflectivity"
GLOSSY_PROPERTY = "rls_glossy"
GHOST_RATIO_PROPERTY = "rls_ghost_ratio"

# A Principled BSDF reflects like a mirror when it is smooth and metallic or clear.
GLOSSY_MAX_ROUGHNESS = 0.1
GLOSSY_MIN_METALLIC = 0.9
GLOSSY_MIN_TRANSMISSION = 0.9


def _principled(material):
    if material.node_tree is not None:  # use_nodes is deprecated (always on in 5.x)
        for node in material.node_tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                return node
    return None


def _luminance(rgb):
    r, g, b = rgb[:3]
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def _input(node, name, default):
    sock = node.inputs.get(name)
    return float(sock.default_value) if sock is not None else default


def is_glossy(material, node=None):
    """The ``rls_glossy`` property when set, else Principled BSDF thresholds: roughness
    <= 0.1 with metallic >= 0.9 or transmission >= 0.9 (else the viewport settings)."""
    if GLOSSY_PROPERTY in material:
        return bool(material[GLOSSY_PROPERTY])
    if node is not None:
        rough = _input(node, "Roughness", 0.5)
        metal = _input(node, "Metallic", 0.0)
        trans = _input(node, "Transmission Weight", _input(node, "Transmission", 0.0))
    else:
        rough, metal, trans = material.roughness, material.metallic, 0.0
    return rough <= GLOSSY_MAX_ROUGHNESS and (metal >= GLOSSY_MIN_METALLIC
                                              or trans >= GLOSSY_MIN_TRANSMISSION)


def material_info(material):
    """Reflectivity from the ``rls_reflectivity`` property, else the luminance of the
    Principled BSDF base colour (else the viewport diffuse colour); glossiness from
    ``is_glossy``; ghost ratio from ``rls_ghost_ratio`` (default 0.5)."""
    node = _principled(material)
    if REFLECTIVITY_PROPERTY in material:
        refl = float(material[REFLECTIVITY_PROPERTY])
    elif node is not None:
        refl = _luminance(node.inputs["Base Color"].default_value)
    else:
        refl = _luminance(material.diffuse_color)
    glossy = is_glossy(material, node)
    ratio = float(material.get(GHOST_RATIO_PROPERTY, 0.5))
    return MaterialInfo(material.name, min(max(refl, 0.0), 1.0), glossy, ratio)
