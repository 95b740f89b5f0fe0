"""What went wrong in a SUMO XML file, said once for every reader of them."""


def parse_reason(exc):
    """An ``xml.etree.ElementTree.ParseError`` as 'what at line N' (line '?' when the
    parser gives none)."""
    line = exc.position[0] if getattr(exc, "position", None) else "?"
    return f"{str(exc).split(':')[0]} at line {line}"
