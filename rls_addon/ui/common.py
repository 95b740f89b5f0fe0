"""What the panels and menus share: wrapped text."""

import textwrap


def wrapped(layout, text, width=48):
    col = layout.column(align=True)
    for line in textwrap.wrap(text, width) or [""]:
        col.label(text=line)
