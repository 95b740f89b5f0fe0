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
"""

import json
from json.encoder import encode_basestring_ascii

_FLOAT = float.__repr__
_INT = int.__repr__


class _Unusual(Exception):
    """A value the fast path leaves to ``json.dumps``."""


def dumps(obj, indent, sort_keys=False):
    """``json.dumps(obj, indent=indent, sort_keys=sort_keys, allow_nan=False)``."""
    out = []
    try:
        _value(obj, out, "\n", " " * int(indent), sort_keys)
    except (_Unusual, RecursionError):
        return json.dumps(obj, indent=indent, sort_keys=sort_keys, allow_nan=False)
    return "".join(out)


def _scalar(v):
    """The text of a plain scalar, or None when ``v`` is not one."""
    t = type(v)
    if t is float:
        if v - v != 0.0:  # NaN or infinity: json's decision
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
    return None


def _value(v, out, newline, step, sort_keys):
    text = _scalar(v)
    if text is not None:
        out.append(text)
        return
    t = type(v)
    if t is dict:
        _object(v, out, newline, step, sort_keys)
    elif t is list or t is tuple:
        _array(v, out, newline, step, sort_keys)
    else:
        raise _Unusual


def _numbers(items):
    """The texts of a list of plain floats and ints, or None when it holds anything
    else."""
    texts = []
    for x in items:
        t = type(x)
        if t is float:
            if x - x != 0.0:
                raise _Unusual
            texts.append(_FLOAT(x))
        elif t is int:
            texts.append(_INT(x))
        else:
            return None
    return texts


def _array(items, out, newline, step, sort_keys):
    if not items:
        out.append("[]")
        return
    inner = newline + step
    texts = _numbers(items)
    if texts is not None:  # numbers: joined in one call
        out.append("[" + inner + ("," + inner).join(texts) + newline + "]")
        return
    out.append("[")
    first = True
    for x in items:
        out.append(inner if first else "," + inner)
        first = False
        _value(x, out, inner, step, sort_keys)
    out.append(newline + "]")


def _object(d, out, newline, step, sort_keys):
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
        text = _scalar(x)
        if text is not None:
            out.append(text)
        else:
            _value(x, out, inner, step, sort_keys)
    out.append(newline + "}")
