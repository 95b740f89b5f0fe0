"""Output file names from a template such as ``{scene}/{sensor}/{frame:06d}``."""

import os
import pathlib
import string

from ...errors import OutputError
from .formats import FORMATS
from .names import sanitize_name

# Point files of other kinds: a template ending in one of these (or in another output
# format's extension) is a mistake, not part of the name
_OTHER_EXT = {".bin", ".laz", ".xyz", ".npy"}


def output_path(directory, template, *, scene, sensor, frame, fmt):
    """Render ``template`` under ``directory`` and add the format's extension.

    Placeholders: ``{scene}``, ``{sensor}`` (sanitised names) and ``{frame}``
    (an int, so ``{frame:06d}`` works). The template's own slashes make
    sub-directories; a result that is absolute or climbs out of ``directory``
    through ``..`` is refused with ``OutputError``.
    """
    ext = FORMATS.get(fmt).extension
    try:
        for _, name, _, _ in string.Formatter().parse(str(template)):
            if name is not None and name not in ("scene", "sensor", "frame"):
                # '{frame.__class__}', '{scene[0]}': an attribute or item of a placeholder
                # (str.format reads them) named a file "<class 'int'>.pcd"
                raise KeyError(name)
        rendered = str(template).format(
            scene=sanitize_name(scene), sensor=sanitize_name(sensor), frame=int(frame)
        )
    except KeyError as exc:
        raise OutputError(
            f"output template {template!r} uses unknown placeholder {{{exc.args[0]}}}; "
            "use {scene}, {sensor} and {frame}"
        ) from None
    except (ValueError, IndexError, TypeError) as exc:
        raise OutputError(f"output template {template!r} is malformed: {exc}") from None
    rel = pathlib.PurePosixPath(rendered.replace("\\", "/"))
    if not rendered.strip() or rel.is_absolute() or pathlib.PureWindowsPath(rendered).drive:
        raise OutputError(f"output template {template!r} must give a relative file name, got {rendered!r}")
    if ".." in rel.parts:
        raise OutputError(f"output template {template!r} leaves the output directory ({rendered!r})")
    if rendered.endswith(("/", "\\")) or rel.name in ("", "."):
        raise OutputError(f"output template {template!r} names a directory, not a file ({rendered!r})")
    suffix = rel.suffix.lower()
    if suffix != ext:
        if suffix in _OTHER_EXT | {f.extension for f in FORMATS if f.extension}:
            raise OutputError(
                f"output template {template!r} ends in {rel.suffix} but the format {fmt} writes {ext} files"
            )
        rel = rel.with_name(rel.name + ext)
    base = pathlib.Path(directory)
    out = base.joinpath(*rel.parts)
    root = os.path.abspath(base)
    if os.path.commonpath([root, os.path.abspath(out)]) != root:
        raise OutputError(f"output template {template!r} leaves the output directory")
    return out
