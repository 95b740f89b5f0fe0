"""LZF compression (the codec of PCD ``binary_compressed``), in numpy.

Stream format (liblzf, as read by PCL and Open3D):

* control byte ``c < 32``: a literal run, ``c + 1`` bytes follow verbatim;
* control byte ``c >= 32``: a back reference of ``(c >> 5) + 2`` bytes
  (``c >> 5 == 7`` means "read one more length byte and add it"), from
  ``((c & 31) << 8 | next_byte) + 1`` bytes back in the output. A reference may
  overlap the bytes it produces (run-length style).

The compressor is greedy like liblzf but finds matches differently: instead of
a hash table walked byte by byte (too slow in Python) it tests a small set of
candidate distances for every position at once with numpy and keeps the
longest match. The candidate distances are chosen by the caller; for the
column-major buffers PCD compresses, multiples of the field size find the
repetition that matters (constant labels, zero ghost flags, ring patterns).
Output is a valid LZF stream any decoder reads; it is somewhat larger than
liblzf's on data whose repeats sit at other distances. The Python loop runs
once per emitted back reference, not once per byte.
"""

import numpy as np

from ...errors import InputError

MAX_OFFSET = 8192  # 13-bit distance
MAX_MATCH = 264  # 7 + 255 + 2
MAX_LITERAL = 32
MIN_MATCH = 4  # a 3-byte match saves nothing once it splits a literal run

DEFAULT_OFFSETS = (1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192)
_CHUNK = 1 << 20


def _best_matches(data, start, stop, offsets, lo):
    """Longest match length and its distance for every position in [start, stop).

    Only references to positions >= ``lo`` are considered. Lengths below
    ``MIN_MATCH`` are left at 0.
    """
    n = len(data)
    size = stop - start
    best_len = np.zeros(size, dtype=np.int32)
    best_off = np.zeros(size, dtype=np.int32)
    for c0 in range(start, stop, _CHUNK):
        c1 = min(stop, c0 + _CHUNK)
        end = min(n, c1 + MAX_MATCH)  # look-ahead so runs near c1 are not cut
        for d in offsets:
            d = int(d)
            if d < 1 or d > MAX_OFFSET:
                continue
            first = max(c0, lo + d)
            if first >= c1:
                continue
            eq = (data[first:end] == data[first - d:end - d]).view(np.int8)
            edge = np.diff(eq, prepend=np.int8(0), append=np.int8(0))
            s = np.flatnonzero(edge == 1)
            e = np.flatnonzero(edge == -1)
            # positions p in a run [s, e) that still have MIN_MATCH bytes to go
            last = np.minimum(e - MIN_MATCH + 1, c1 - first)
            keep = last > s
            if not keep.any():
                continue
            s, e, last = s[keep], e[keep], last[keep]
            counts = last - s
            total = int(counts.sum())
            base = np.cumsum(counts) - counts
            pos = np.arange(total, dtype=np.int64) + np.repeat(s - base, counts)
            run = np.minimum(np.repeat(e, counts) - pos, MAX_MATCH).astype(np.int32)
            tgt = pos + (first - start)
            better = run > best_len[tgt]
            tgt = tgt[better]
            best_len[tgt] = run[better]
            best_off[tgt] = d
    return best_len, best_off


def _literals(block):
    """Encode ``block`` (uint8 array) as literal runs of at most 32 bytes."""
    k = len(block)
    if k == 0:
        return b""
    full, rest = divmod(k, MAX_LITERAL)
    parts = []
    if full:
        body = block[: full * MAX_LITERAL].reshape(full, MAX_LITERAL)
        ctrl = np.full((full, 1), MAX_LITERAL - 1, dtype=np.uint8)
        parts.append(np.hstack([ctrl, body]).tobytes())
    if rest:
        parts.append(bytes((rest - 1,)) + block[full * MAX_LITERAL:].tobytes())
    return b"".join(parts)


def _reference(length, offset):
    off = offset - 1
    ln = length - 2
    if ln < 7:
        return bytes(((ln << 5) | (off >> 8), off & 0xFF))
    return bytes(((7 << 5) | (off >> 8), ln - 7, off & 0xFF))


def compress(data, segments=None):
    """LZF-compress ``data`` (bytes-like); returns ``bytes``.

    ``segments`` is an optional list of ``(start, stop, offsets)``: matches for
    positions in each segment are searched at those distances, within the
    segment. Without it the whole buffer is one segment with
    ``DEFAULT_OFFSETS``.
    """
    buf = np.frombuffer(bytes(data), dtype=np.uint8)
    n = len(buf)
    if n == 0:
        return b""
    if segments is None:
        segments = [(0, n, DEFAULT_OFFSETS)]
    best_len = np.zeros(n, dtype=np.int32)
    best_off = np.zeros(n, dtype=np.int32)
    for s0, s1, offs in segments:
        if s1 > s0:
            bl, bo = _best_matches(buf, s0, s1, offs, s0)
            best_len[s0:s1] = bl
            best_off[s0:s1] = bo
    has = best_len > 0
    # next position >= i that starts a match (n if none)
    nxt = np.where(has, np.arange(n, dtype=np.int64), n)
    nxt = np.minimum.accumulate(nxt[::-1])[::-1]
    out = []
    i = 0  # next input byte to encode
    while i < n:
        length = int(best_len[i])
        if length == 0:
            j = int(nxt[i])
            out.append(_literals(buf[i:j]))
            i = j
            continue
        out.append(_reference(length, int(best_off[i])))
        i += length
    return b"".join(out)


def decompress(data, expected_size):
    """Decode an LZF stream; raises ``InputError`` if it is corrupt."""
    src = bytes(data)
    out = bytearray()
    ip = 0
    n = len(src)
    while ip < n:
        ctrl = src[ip]
        ip += 1
        if ctrl < 32:
            run = ctrl + 1
            if ip + run > n:
                raise InputError("LZF literal run past end of input")
            out += src[ip:ip + run]
            ip += run
            continue
        length = ctrl >> 5
        if length == 7:
            if ip >= n:
                raise InputError("LZF stream truncated")
            length += src[ip]
            ip += 1
        if ip >= n:
            raise InputError("LZF stream truncated")
        offset = ((ctrl & 31) << 8 | src[ip]) + 1
        ip += 1
        length += 2
        if offset > len(out):
            raise InputError("LZF back reference before start of output")
        startp = len(out) - offset
        if offset >= length:
            out += out[startp:startp + length]
        else:
            pattern = bytes(out[startp:])
            reps = -(-length // offset)
            out += (pattern * reps)[:length]
    if len(out) != expected_size:
        raise InputError(f"LZF data decodes to {len(out)} bytes, expected {expected_size}")
    return bytes(out)
