"""What ``save_blend`` checks before it places a .blend (``core/output/io/blend_file``):
files Blender writes, compressed and not, are whole; the same files cut short at any
point, with a byte more, or with a byte of their seek table changed, are not."""

import os

import pytest

from rls_addon.core.output.io.blend_file import incomplete_blend

from .conftest import bpy, mesh_object


def written(tmp_path, compress):
    mesh_object("Box", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 1)], [(0, 1, 2, 3)])
    path = tmp_path / f"scene_{int(compress)}.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=compress, copy=True)
    return path


@pytest.mark.parametrize("compress", [True, False], ids=["zstd", "plain"])
def test_whole_files_pass_and_cut_ones_do_not(scene, tmp_path, compress):
    path = written(tmp_path, compress)
    assert incomplete_blend(path) is None
    data = path.read_bytes()
    cut = tmp_path / "cut.blend"
    # every length in the last 64 bytes (the seek table, the end block), then 200 more
    lengths = sorted(set(range(max(0, len(data) - 64), len(data)))
                     | set(range(0, len(data), max(1, len(data) // 200))))
    for n in lengths:
        cut.write_bytes(data[:n])
        assert incomplete_blend(cut) is not None, (n, len(data))
    cut.write_bytes(data + b"\0")
    assert incomplete_blend(cut) is not None
    if compress:  # a frame size in the seek table one off: the frames do not add up
        frames = int.from_bytes(data[-9:-5], "little")
        entry = len(data) - 9 - 8 * frames
        changed = bytearray(data)
        changed[entry] ^= 1
        cut.write_bytes(bytes(changed))
        assert "add up" in incomplete_blend(cut)
    assert "cannot read it back" in incomplete_blend(tmp_path / "missing.blend")
    os.unlink(cut)
