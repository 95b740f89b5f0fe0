"""Indented JSON text (``output/io/json_text.dumps``) is ``json.dumps``' own, character
for character: random nested documents, the sidecars and dataset metas a run writes,
and the values the fast path hands over to ``json`` (which then answers, or raises)."""

import json
import math

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
