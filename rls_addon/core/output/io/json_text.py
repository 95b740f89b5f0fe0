"""Indented JSON text as ``json.dumps(obj, indent=..., sort_keys=..., allow_nan=False)``
writes it, character for character, in a fraction of its time.

With an indent, Python's ``json`` encodes in pure Python, a generator per nested
value: a driving lidar's sidecar (its pose knots, a box per road user) or a dataset
frame's meta took 3-4 ms of every frame's writing, on the thread that writes behind
the scan, holding Python's global lock that the scan needs too. Here each value goes straight
into one list of pieces, and a list of plain floats or ints (matrices, times,
positions) is joined in one call. Anything outside plain JSON values (a dict with keys
other than strings, a subclass of a JSON type, a value ``json`` refuses, such as NaN,
infinity or a cycle) is handed to ``json.dumps`` itself, which gives its own text or
raises its own error.

``dumps(..., plain=fn)`` writes ``json.dumps(fn(obj), ...)`` for ``fn`` the sidecar's
``_plain`` (numpy arrays and scalars to Python values, non-finite floats to null, paths
to text), converting each value as it is written instead of copying the whole
document first: the copy took as long as the writing (1.2 ms of a driving lidar's
sidecar, on the writer's thread, holding the lock the scan needs). What the fast path
does not take (a subclass of a dict or list, a key other than a string) goes through
``fn`` and ``json.dumps`` whole.
"""

import json
import pathlib
from json.encoder import encode_basestring_ascii

import numpy as np

_FLOAT = float.__repr__
_INT = int.__repr__


class _Unusual(Exception):
    """A value the fast path leaves to ``json.dumps``."""


def dumps(obj, indent, sort_keys=False, plain=None):
    """``json.dumps(obj, indent=indent, sort_keys=sort_keys, allow_nan=False)``; with
    ``plain`` (the sidecar's ``_plain``), of ``plain(obj)``."""
    out = []
    try:
        _value(obj, out, "\n", " " * int(indent), sort_keys, plain is not None)
    except (_Unusual, RecursionError):
        return json.dumps(obj if plain is None else plain(obj), indent=indent,
                          sort_keys=sort_keys, allow_nan=False)
    return "".join(out)


def _scalar(v, plain=False):
    """The text of a plain scalar, or None when ``v`` is not one. ``plain``: a
    non-finite float is null, a numpy scalar its Python value, a path its text."""
    t = type(v)
    if t is float:
        if v - v != 0.0:  # NaN or infinity: json's decision, or plain's null
            if plain:
                return "null"
            raise _Unusual
        return _FLOAT(v)
    if t is str:
        return encode_basestring_ascii(v)
    if t is int:
        return _INT(v)
    if v is None:
        return "null"
    if v is True:
        return "true"
    if v is False:
        return "false"
    if plain:
        if isinstance(v, np.generic):
            return _scalar(v.item(), plain)
        if isinstance(v, pathlib.PurePath):
            return encode_basestring_ascii(str(v))
    return None


def _value(v, out, newline, step, sort_keys, plain=False):
    text = _scalar(v, plain)
    if text is not None:
        out.append(text)
        return
    t = type(v)
    if t is dict:
        _object(v, out, newline, step, sort_keys, plain)
    elif t is list or t is tuple:
        _array(v, out, newline, step, sort_keys, plain)
    elif plain and t is np.ndarray:
        _value(v.tolist(), out, newline, step, sort_keys, plain)
    else:
        raise _Unusual


def _numbers(items, plain=False):
    """The texts of a list of plain floats and ints, or None when it holds anything
    else."""
    texts = []
    for x in items:
        t = type(x)
        if t is float:
            if x - x != 0.0:
                if not plain:
                    raise _Unusual
                texts.append("null")
                continue
            texts.append(_FLOAT(x))
        elif t is int:
            texts.append(_INT(x))
        else:
            return None
    return texts


def _array(items, out, newline, step, sort_keys, plain=False):
    if not items:
        out.append("[]")
        return
    inner = newline + step
    texts = _numbers(items, plain)
    if texts is not None:  # numbers: joined in one call
        out.append("[" + inner + ("," + inner).join(texts) + newline + "]")
        return
    out.append("[")
    first = True
    for x in items:
        out.append(inner if first else "," + inner)
        first = False
        _value(x, out, inner, step, sort_keys, plain)
    out.append(newline + "]")


def _object(d, out, newline, step, sort_keys, plain=False):
    if not d:
        out.append("{}")
        return
    items = d.items()
    if sort_keys:
        if any(type(k) is not str for k in d):
            raise _Unusual
        items = sorted(items)
    inner = newline + step
    lead = "{" + inner
    for k, x in items:
        if type(k) is not str:
            raise _Unusual
        out.append(lead + encode_basestring_ascii(k) + ": ")
        lead = "," + inner
        text = _scalar(x, plain)
        if text is not None:
            out.append(text)
        else:
            _value(x, out, inner, step, sort_keys, plain)
    out.append(newline + "}")
