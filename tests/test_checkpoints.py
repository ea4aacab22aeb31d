"""Checkpoints as data (issue 69): a job's result goes to disk as arrays and JSON and comes back equal, loading one
runs no code, a record cut short is dropped, and an older pickled checkpoint is refused in one line."""

import pickle
from pathlib import Path

import numpy as np
import pytest

from rc1_drake.config import Rc1Error
from rc1_drake.measurements import load_campaign
from rc1_drake.sysid.evaluate import Checkpoint
from rc1_drake.sysid.records import decode, encode, read_records

SHIPPED = Path(__file__).resolve().parents[1] / "data" / "paper_campaign"


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
    if isinstance(a, tuple | list):
        return type(a) is type(b) and len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if hasattr(a, "__dataclass_fields__"):
        return type(a) is type(b) and all(_equal(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
    return a == b or (a != a and b != b)  # NaN


def test_what_the_jobs_return_comes_back_equal_from_a_record():
    """The results a checkpoint keeps (residuals, a residual and its Jacobian, Eq. 6's float, a noise-free twin's
    Trial with its angle noise, inf and NaN) round-trip exactly; an object it cannot keep is refused as it is
    written."""
    trial = load_campaign(SHIPPED).trials[0]
    values = [
        np.linspace(0.0, 1.0, 7),
        (np.eye(3), np.arange(6.0).reshape(2, 3)),
        2.5,
        (trial, 0.0042),
        {"a": [1, float("inf"), float("nan")], 3: None, (1, 2): "x"},
        (np.array([1, 2], dtype=np.int64), np.float64(0.1), True),
    ]
    for value in values:
        record = encode("k", value)
        key, back = decode(record[8:])
        assert key == "k" and _equal(value, back), value
    with pytest.raises(TypeError, match="a checkpoint keeps arrays, numbers, strings"):
        encode("k", object())
    with pytest.raises(TypeError, match="not of objects"):
        encode("k", np.array([object()]))


def test_a_checkpoint_resumes_its_records_and_drops_one_cut_short(tmp_path):
    first = Checkpoint(tmp_path)
    first.put("a", np.arange(3.0))
    first.put("b", (1.0, np.ones(2)))
    with open(first.path, "ab") as f:
        f.write(encode("c", np.zeros(100))[:50])  # the interruption cut the third record
    again = Checkpoint(tmp_path)
    assert sorted(again.results) == ["a", "b"] and again.loaded == {"a", "b"}
    np.testing.assert_array_equal(again.take("a"), np.arange(3.0))
    assert again.resumed == 1
    assert list(read_records(first.path)) == ["a", "b"]


def test_loading_a_record_runs_no_code_and_an_older_pickled_checkpoint_is_refused(tmp_path):
    """An archive whose array is a pickle is not read (allow_pickle=False); a folder with an older rc1's
    results-*.pkl is refused, naming the file, before anything loads it."""
    import io

    buffer = io.BytesIO()
    np.savez(buffer, key=np.array("k"), tree=np.array('{"__array__": 0}'), a0=np.array([{"x": 1}], dtype=object))
    with pytest.raises(ValueError, match="allow_pickle"):
        decode(buffer.getvalue())
    old = tmp_path / "results-0123456789abcdef.pkl"
    old.write_bytes(pickle.dumps(("k", 1.0)))
    with pytest.raises(Rc1Error, match=r"results-0123456789abcdef\.pkl: a checkpoint of an older rc1 .*: delete it"):
        Checkpoint(tmp_path)
