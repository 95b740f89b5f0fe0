"""Whether a .blend file Blender has just written is whole.

Blender's save does not always raise when the disk fills: it has been seen to return
after writing 192,512 bytes of a 265,000-byte scene, a file it then refuses to open
("Missing DNA block"). So the command line checks what was written before it places it
(``blender/files.save_blend``), from the file's own structure, without Blender:

- compressed (what RLS writes: ``save_as_mainfile(compress=True)``): Zstandard in its
  seekable format, as Blender writes it (``blenloader/intern/writefile.cc``,
  ``ZstdWriteWrap::write_seekable_frames``, no checksums; the format: facebook/zstd
  ``contrib/seekable_format/zstd_seekable_compression_format.md``):
  frames, then a skippable frame (magic 0x184D2A5E) holding one entry per frame
  (compressed size, decompressed size, [checksum]) and a 9-byte footer (number of frames,
  descriptor, magic 0x8F92EAB1). The file is whole when the footer is there, the table's
  frame sizes add up to the file's size, and every frame starts with the Zstandard magic
  where the table says.
- uncompressed: the "BLENDER" header, and the file ends with the header of an ``ENDB``
  block (Blender's end-of-file block, without data): 20 bytes with 4-byte pointers and
  24 with 8-byte ones ("BLENDER_v..." / "BLENDER-v..."), 32 in the large block headers
  of Blender 5.0 ("BLENDER17-01v0500": header length 17, 8-byte pointers, block header
  format 01).
"""

import os
import struct

ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
SKIPPABLE_MAGIC = 0x184D2A5E
SEEKABLE_MAGIC = 0x8F92EAB1
FOOTER = 9            # number of frames (u32), descriptor (u8), magic (u32)
SKIPPABLE_HEADER = 8  # magic (u32), frame size (u32)


def incomplete_blend(path):
    """Why the .blend at ``path`` is not whole, or None when it is."""
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as fh:
            head = fh.read(12)
            if head.startswith(ZSTD_MAGIC):
                return _seekable_zstd(fh, size)
            if head.startswith(b"BLENDER"):
                block = _end_block_size(head)
                if block is None:
                    return f"a .blend header this check does not know: {head!r}"
                fh.seek(max(0, size - block))
                return None if size > block + 12 and fh.read(4) == b"ENDB" else \
                    f"no end-of-file block at its end, {size:,} bytes written"
    except OSError as exc:
        return f"cannot read it back: {exc.strerror or exc}"
    return f"not a .blend file: {size:,} bytes starting {head[:8]!r}"


def _end_block_size(head):
    """The size of the ENDB block (a block header) in a file with header ``head``."""
    if head[7:9].isdigit():  # Blender 5.0: "BLENDER" + header length + pointer + format
        return 32 if head[9:12] == b"-01" else None
    return {b"_": 20, b"-": 24}.get(head[7:8])


def _seekable_zstd(fh, size):
    if size < SKIPPABLE_HEADER + FOOTER:
        return f"only {size:,} bytes written"
    fh.seek(size - FOOTER)
    frames, descriptor, magic = struct.unpack("<IBI", fh.read(FOOTER))
    if magic != SEEKABLE_MAGIC:
        return f"no seek table at the end of its compressed stream, {size:,} bytes written"
    entry = 12 if descriptor & 0x80 else 8  # with a checksum per frame, or without
    table = SKIPPABLE_HEADER + frames * entry + FOOTER
    if table > size:
        return f"a seek table of {frames:,} frames in {size:,} bytes"
    fh.seek(size - table)
    skip_magic, skip_size = struct.unpack("<II", fh.read(SKIPPABLE_HEADER))
    if skip_magic != SKIPPABLE_MAGIC or skip_size != table - SKIPPABLE_HEADER:
        return "its seek table is damaged"
    rows = fh.read(frames * entry)
    sizes = [struct.unpack_from("<I", rows, i * entry)[0] for i in range(frames)]
    if sum(sizes) + table != size:
        return f"its frames add up to {sum(sizes) + table:,} bytes, the file has {size:,}"
    offset = 0
    for n, frame_size in enumerate(sizes):
        fh.seek(offset)
        if fh.read(4) != ZSTD_MAGIC:
            return f"frame {n + 1} of {frames} does not start where the seek table says"
        offset += frame_size
    return None


__all__ = ["incomplete_blend"]
