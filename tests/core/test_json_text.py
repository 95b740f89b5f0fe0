"""Indented JSON text (``output/io/json_text.dumps``) is ``json.dumps``' own, character
for character: random nested documents, the sidecars and dataset metas a run writes,
and the values the fast path hands over to ``json`` (which then answers, or raises)."""

import json
import math
import pathlib

import numpy as np
import pytest

from rls_addon.core.output.io.json_text import dumps


def document(rng, depth=0):
    """A random JSON-ready value: dicts, lists, tuples, strings (unicode and escapes),
    floats of every size, ints, booleans, None, empty containers."""
    kind = int(rng.integers(0, 10 if depth < 4 else 6))
    if kind == 0:
        return float(rng.normal() * 10.0 ** rng.integers(-320, 300))
    if kind == 1:
        return int(rng.integers(-2 ** 62, 2 ** 62)) * int(rng.integers(1, 2 ** 20))
    if kind == 2:
        return str(rng.choice(["", "a", "caf\u00e9", "tab\there", 'q"uote', "back\\slash",
                               "\u2603 snow", "line\nbreak", "\x00\x1f"]))
    if kind == 3:
        return [None, True, False][int(rng.integers(0, 3))]
    if kind == 4:
        return [float(x) for x in rng.normal(size=int(rng.integers(0, 6)))]
    if kind == 5:
        return [int(x) for x in rng.integers(-5, 5, int(rng.integers(0, 4)))] + [1.5]
    if kind in (6, 7):
        n = int(rng.integers(0, 5))
        items = [document(rng, depth + 1) for _ in range(n)]
        return items if kind == 6 else tuple(items)
    n = int(rng.integers(0, 5))
    return {str(rng.choice(["b", "a", "\u00e9t\u00e9", "z z", "key", "x1", "x10"])) + str(j):
            document(rng, depth + 1) for j in range(n)}


@pytest.mark.parametrize("indent", [1, 2, 4])
@pytest.mark.parametrize("sort_keys", [False, True])
def test_random_documents_read_as_json_writes_them(indent, sort_keys):
    rng = np.random.default_rng(indent * 10 + sort_keys)
    for _ in range(300):
        doc = document(rng)
        assert dumps(doc, indent, sort_keys) == json.dumps(doc, indent=indent,
                                                           sort_keys=sort_keys,
                                                           allow_nan=False)


def test_what_json_decides_is_left_to_it():
    """Keys other than strings, subclasses of JSON types and numpy scalars, non-finite
    floats and cycles go to ``json.dumps``: its text, or its error."""
    class Number(float):
        pass

    for doc in ({1: "a", 2.5: "b", None: 3, True: [1]}, {"x": Number(0.1)},
                [True, 1, 2.0], {"b": {1: 2}}, [1, [2, [3, {"k": (4, 5.5)}]]]):
        for sort_keys in (False, True):
            try:
                want = json.dumps(doc, indent=2, sort_keys=sort_keys, allow_nan=False)
            except TypeError:
                with pytest.raises(TypeError):
                    dumps(doc, 2, sort_keys)
                continue
            assert dumps(doc, 2, sort_keys) == want
    for bad in ([1.0, math.nan], {"a": [math.inf]}, {"a": -math.inf}):
        with pytest.raises(ValueError):
            dumps(bad, 2)
    assert dumps({"a": np.float64(0.1)}, 1) == json.dumps({"a": np.float64(0.1)}, indent=1)
    with pytest.raises(TypeError):
        dumps({"a": np.float32(1.0)}, 1)
    loop = []
    loop.append(loop)
    with pytest.raises(ValueError, match="Circular"):
        dumps(loop, 2)


def numpy_document(rng, depth=0):
    """``document`` with what a sidecar's info holds besides plain JSON: numpy arrays
    (float, int, bool; empty, 0-d, nested), numpy scalars, non-finite floats, paths,
    keys other than strings, subclasses of dict, list and float."""
    class Number(float):
        pass

    class Table(dict):
        pass

    kind = int(rng.integers(0, 12 if depth < 3 else 8))
    values = [math.nan, math.inf, -math.inf, np.float64(math.nan), np.float64(0.1),
              np.float32(0.5), np.int64(-3), np.bool_(True), np.str_("caf\u00e9"),
              Number(2.5), pathlib.PurePosixPath("/tmp/a b.pcd"), 1.25, "x", None]
    if kind < 4:
        return values[int(rng.integers(0, len(values)))]
    if kind == 4:
        a = rng.normal(size=tuple(int(k) for k in rng.integers(0, 4, int(rng.integers(0, 3)))))
        a[a > 1.0] = np.inf
        a[a < -1.5] = np.nan
        return a
    if kind == 5:
        return rng.integers(-9, 9, int(rng.integers(0, 5))) > 0 if rng.random() < 0.3 \
            else rng.integers(-9, 9, (2, int(rng.integers(0, 3))))
    if kind in (6, 7):
        return document(rng, depth + 2)
    n = int(rng.integers(0, 5))
    items = [numpy_document(rng, depth + 1) for _ in range(n)]
    if kind == 8:
        return items
    if kind == 9:
        return tuple(items)
    keys = ["b", "a", "k1", 3, "3", 2.5, True, None, "\u00e9t\u00e9"]
    d = {keys[int(rng.integers(0, len(keys)))]: v for v in items}
    return Table(d) if kind == 10 and rng.random() < 0.5 else d


@pytest.mark.parametrize("sort_keys", [False, True])
def test_a_sidecar_is_written_as_its_plain_copy_would_be(sort_keys):
    """``dumps(info, plain=sidecar._plain)``, converting as it writes, is
    ``json.dumps(_plain(info))`` character for character: numpy arrays and scalars,
    non-finite floats (null), paths, keys other than strings (and two keys that read
    the same), subclasses; what ``_plain`` leaves unwritable raises as it did."""
    from rls_addon.core.output.io.sidecar import _plain

    rng = np.random.default_rng(40 + sort_keys)
    for _ in range(400):
        doc = {"info": numpy_document(rng), "n": np.arange(3.0)}
        try:
            want = json.dumps(_plain(doc), indent=2, sort_keys=sort_keys, allow_nan=False)
        except TypeError:  # keys of mixed types cannot be sorted
            with pytest.raises(TypeError):
                dumps(doc, 2, sort_keys, plain=_plain)
            continue
        assert dumps(doc, 2, sort_keys, plain=_plain) == want
    with pytest.raises(TypeError):
        dumps({"a": object()}, 2, plain=_plain)


def test_a_sidecars_numpy_values_take_the_fast_path(monkeypatch):
    """Arrays, numpy scalars, NaN and paths are written without handing the document
    to ``json`` (whose indented encoder is the slow path this module replaces)."""
    from rls_addon.core.output.io import json_text
    from rls_addon.core.output.io.sidecar import _plain

    doc = {"m": np.eye(4), "t": np.float64(0.5), "bad": [1.0, math.nan], "ok": np.bool_(1),
           "path": pathlib.PurePosixPath("a/b.pcd"), "ring": np.arange(3, dtype=np.uint16)}
    want = json.dumps(_plain(doc), indent=2, sort_keys=True, allow_nan=False)

    def refuse(*args, **kwargs):
        raise AssertionError("handed to json.dumps")

    monkeypatch.setattr(json_text.json, "dumps", refuse)
    assert dumps(doc, 2, True, plain=_plain) == want
