"""Frames as a user writes them: '5', '1-10' or '1-10:2' (the command line's --frames and
its kin, and the panels' frame fields)."""

from ..errors import SceneError

# Blender's last frame (MAXFRAME, the hard maximum of Scene.frame_end; traffic.fcd's too)
MAX_FRAME = 1_048_574


def parse_frames(text, current, option="--frames"):
    """'5' -> [5]; '1-10' -> 1..10; '1-10:2' -> 1,3,..,9; None -> [current]. ``option``
    names the field in the error of a text that is none of these."""
    if text is None:
        return [current]
    try:
        rng, _, step = text.partition(":")
        a, sep, b = rng.partition("-")
        start, end = int(a), int(b) if sep else int(a)
        step = int(step) if step else 1
    except ValueError:
        raise SceneError(f"{option}: expected N, A-B or A-B:STEP, got '{text}'") from None
    if end < start or step < 1:
        raise SceneError(f"{option}: empty range '{text}'")
    if end > MAX_FRAME:
        raise SceneError(f"{option}: frame {end} is past Blender's last frame ({MAX_FRAME}), "
                         f"got '{text}'")
    return list(range(start, end + 1, step))
