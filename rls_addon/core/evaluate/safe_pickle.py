"""Reading a pickle (OpenPCDet's ``result.pkl``) without running what it names.

A pickle is a program: each global it names is imported and may be called while it
loads, so ``pickle.load`` of a file from elsewhere can run anything (``os.system``).
``load_pickle`` admits only the globals that plain data and numpy arrays need and
refuses every other one, by name, before it is imported or called:

- numpy arrays and scalars: ``ndarray``, ``dtype``, the array rebuilders
  ``_reconstruct`` and ``_frombuffer`` (protocol 5) and ``scalar``, under numpy 1's
  module names (``numpy.core.multiarray``, ``numpy.core.numeric``) and numpy 2's
  (``numpy._core.*``); each maps to this numpy's own function, whatever its version;
- containers and values: dict, list, tuple, set, frozenset, str, bytes, bytearray,
  int, float, complex, bool, None (most need no global at all), and
  ``collections.OrderedDict``;
- ``_codecs.encode`` with the latin-1 codec only: how protocols 0-2 store bytes.

Torch tensors (``torch._utils._rebuild_tensor_v2``), EasyDicts, any class of the
detector's code base are refused: OpenPCDet's ``result.pkl`` holds numpy arrays and
strings only (``pcdet/datasets/dataset.py``: ``generate_prediction_dicts`` turns
tensors into numpy before ``tools/eval_utils/eval_utils.py`` dumps the list)."""

import builtins
import collections
import io
import pickle

import numpy as np

from ..errors import InputError


def _latin1_encode(text, encoding="utf-8", errors="strict"):
    """``_codecs.encode`` as protocols 0-2 use it for bytes (latin-1), nothing else."""
    if not isinstance(text, str) or str(encoding).lower().replace("_", "-") not in (
            "latin1", "latin-1", "iso-8859-1"):
        raise pickle.UnpicklingError(f"_codecs.encode with {encoding!r} is not admitted")
    return text.encode("latin-1", errors="strict")


def _numpy_names():
    """Each admitted numpy global, by (module, name) of numpy 1 and numpy 2, mapped to
    this numpy's object (found from what it pickles itself, not by module path)."""
    reconstruct = np.zeros(1).__reduce__()[0]
    frombuffer = np.zeros(1).__reduce_ex__(5)[0]
    scalar = np.float64(0).__reduce__()[0]
    out = {("numpy", "ndarray"): np.ndarray, ("numpy", "dtype"): np.dtype}
    for core in ("numpy.core", "numpy._core"):
        out[(f"{core}.multiarray", "_reconstruct")] = reconstruct
        out[(f"{core}.multiarray", "scalar")] = scalar
        out[(f"{core}.numeric", "_frombuffer")] = frombuffer
        out[(f"{core}.multiarray", "ndarray")] = np.ndarray
        out[(f"{core}.multiarray", "dtype")] = np.dtype
    return out


_BUILTINS = {name: getattr(builtins, name)
             for name in ("dict", "list", "tuple", "set", "frozenset", "str", "bytes",
                          "bytearray", "int", "float", "complex", "bool")}
ADMITTED = dict(_numpy_names())
ADMITTED.update({("builtins", k): v for k, v in _BUILTINS.items()})
ADMITTED.update({("__builtin__", k): v for k, v in _BUILTINS.items()})  # protocol 0-2 from py2
ADMITTED[("collections", "OrderedDict")] = collections.OrderedDict
ADMITTED[("_codecs", "encode")] = _latin1_encode


class _Refused(Exception):
    def __init__(self, module, name):
        super().__init__(f"{module}.{name}")
        self.module, self.name = module, name


class RestrictedUnpickler(pickle.Unpickler):
    """An unpickler whose ``find_class`` knows only ``ADMITTED``."""

    def find_class(self, module, name):
        found = ADMITTED.get((module, name))
        if found is None:
            raise _Refused(module, name)
        return found

    def persistent_load(self, pid):
        raise pickle.UnpicklingError("persistent ids are not admitted")


def loads(data, source="the pickle"):
    """The object of pickle bytes ``data``; ``InputError`` naming ``source`` and the
    refused global when it names anything but plain data and numpy arrays."""
    try:
        return RestrictedUnpickler(io.BytesIO(data)).load()
    except _Refused as exc:
        hint = " (a torch tensor: save numpy arrays, as OpenPCDet's result.pkl does)" \
            if exc.module.startswith("torch") else ""
        raise InputError(f"{source}: refused to load: it names {exc.module}.{exc.name}, which "
                         "is not plain data or a numpy array; RLS reads pickles holding "
                         f"only dicts, lists, strings, numbers and numpy arrays{hint}") from None
    except RecursionError:
        raise InputError(f"{source}: not a readable pickle (nested too deeply)") from None
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError,
            IndexError, KeyError, OverflowError, MemoryError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: not a readable pickle ({type(exc).__name__}: {exc})") from None


def load_pickle(path):
    """The object of the pickle file at ``path``, loaded as ``loads`` does."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    return loads(data, str(path))


__all__ = ["ADMITTED", "RestrictedUnpickler", "load_pickle", "loads"]
