"""The restricted unpickler: numpy arrays and plain data in, everything else refused
before it runs."""

import collections
import os
import pickle

import numpy as np
import pytest

from rls_addon.core.errors import InputError
from rls_addon.core.evaluate.safe_pickle import load_pickle, loads


def _result_like():
    ids = np.stack([np.array("000001"), np.array("000002")])  # as OpenPCDet collates
    return [{"name": np.array(["Vehicle", "Cyclist"]), "score": np.float32([0.9, 0.4]),
             "boxes_lidar": np.arange(14, dtype=np.float32).reshape(2, 7),
             "pred_labels": np.array([1, 3]), "frame_id": ids[0],
             "extra": collections.OrderedDict(a={1, 2}, b=(None, True, 2.5, b"x", 3 + 1j)),
             "objects": np.array([1, "a"], dtype=object), "n": np.int64(4)}]


@pytest.mark.parametrize("protocol", [0, 2, 4, 5])
def test_plain_data_and_numpy_arrays_load(protocol):
    data = _result_like()
    back = loads(pickle.dumps(data, protocol=protocol))
    assert back[0]["frame_id"] == "000001" and isinstance(back[0]["frame_id"], np.str_)
    assert back[0]["boxes_lidar"].dtype == np.float32
    np.testing.assert_array_equal(back[0]["boxes_lidar"], data[0]["boxes_lidar"])
    assert list(back[0]["name"]) == ["Vehicle", "Cyclist"]
    assert back[0]["extra"] == data[0]["extra"]
    assert list(back[0]["objects"]) == [1, "a"] and back[0]["n"] == 4


def test_numpy_2_module_names_load():
    """numpy 2 pickles arrays as numpy._core.multiarray._reconstruct (and scalars)."""
    blob = pickle.dumps(_result_like(), protocol=2)
    assert b"cnumpy.core.multiarray\n" in blob
    blob = blob.replace(b"cnumpy.core.multiarray\n", b"cnumpy._core.multiarray\n")
    back = loads(blob)
    np.testing.assert_array_equal(back[0]["boxes_lidar"], _result_like()[0]["boxes_lidar"])


class _Touch:
    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (os.system, (f"touch '{self.path}'",))


class _Eval:
    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        return (eval, (f"open({str(self.path)!r}, 'w').close()",))


class Plain:
    pass


@pytest.mark.parametrize("make, refused", [(_Touch, "system"), (_Eval, "builtins.eval")])
def test_malicious_pickle_is_refused_and_never_runs(tmp_path, make, refused):
    marker = tmp_path / "marker"
    path = tmp_path / "result.pkl"
    path.write_bytes(pickle.dumps([{"frame_id": "000001", "evil": make(marker)}]))
    # the pickle does run under plain pickle (the test can fail)
    pickle.loads(pickle.dumps(make(tmp_path / "proof")))
    assert (tmp_path / "proof").exists()
    with pytest.raises(InputError) as err:
        load_pickle(path)
    assert refused in str(err.value) and str(path) in str(err.value)
    assert not marker.exists()


def test_arbitrary_classes_and_torch_are_refused():
    with pytest.raises(InputError, match=r"test_safe_pickle\.Plain"):
        loads(pickle.dumps(Plain()))
    blob = b"\x80\x02ctorch._utils\n_rebuild_tensor_v2\n)R."
    with pytest.raises(InputError, match=r"torch\._utils\._rebuild_tensor_v2.*torch tensor"):
        loads(blob)
    blob = b"\x80\x02c_codecs\nencode\nX\x02\x00\x00\x00abX\x05\x00\x00\x00rot13\x86R."
    with pytest.raises(InputError, match="not a readable pickle"):
        loads(blob)


def test_garbage_is_one_clear_error(tmp_path):
    path = tmp_path / "result.pkl"
    path.write_bytes(b"not a pickle at all")
    with pytest.raises(InputError, match=r"result\.pkl: not a readable pickle"):
        load_pickle(path)
    with pytest.raises(InputError, match="cannot read"):
        load_pickle(tmp_path / "missing.pkl")
