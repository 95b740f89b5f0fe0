"""What the panels and menus share: the family icons and wrapped text."""

import textwrap

FAMILY_ICONS = {"spinning": "LIGHTPROBE_SPHERE", "mems": "LIGHTPROBE_PLANE",
                "risley": "LIGHTPROBE_VOLUME", "custom": "FILE_TEXT"}


def wrapped(layout, text, width=48):
    col = layout.column(align=True)
    for line in textwrap.wrap(text, width) or [""]:
        col.label(text=line)
