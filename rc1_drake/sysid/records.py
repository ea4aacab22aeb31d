"""A checkpoint's records as data (issue 69): each result an .npz archive of its arrays and a JSON tree that places
them, read back with allow_pickle=False, so that loading a checkpoint runs no code (a pickle can: whoever writes into
the folder would run code as its next user). What a record can hold: arrays of numbers, numbers, strings, None,
tuples, lists, dicts, paths and the measurement dataclasses a job returns (RECORD_TYPES); anything else is refused
when it is written, not lost when it is read."""

import dataclasses
import io
import json
import struct
import zipfile
from pathlib import Path

import numpy as np

_LENGTH = struct.Struct("<Q")  # each record: its byte count, then the archive


def _record_types() -> dict:
    from ..config import Gait, JointGait
    from ..measurements import Stop, Trial

    return {cls.__name__: cls for cls in (Gait, JointGait, Stop, Trial)}


def encode(key: str, value) -> bytes:
    """One record: `key` and `value` as an .npz archive, its byte count first."""
    arrays, types = [], _record_types()

    def tree(v):
        if isinstance(v, np.ndarray):
            if v.dtype.hasobject:
                raise TypeError("a checkpoint keeps arrays of numbers or strings, not of objects")
            arrays.append(v)
            return {"__array__": len(arrays) - 1}
        if isinstance(v, np.generic):
            return v.item()
        if v is None or isinstance(v, bool | int | float | str):
            return v
        if isinstance(v, tuple):
            return {"__tuple__": [tree(x) for x in v]}
        if isinstance(v, list):
            return [tree(x) for x in v]
        if isinstance(v, dict):
            return {"__dict__": [[tree(k), tree(x)] for k, x in v.items()]}
        if isinstance(v, Path):
            return {"__path__": str(v)}
        if dataclasses.is_dataclass(v) and types.get(type(v).__name__) is type(v):
            fields = {f.name: tree(getattr(v, f.name)) for f in dataclasses.fields(v)}
            return {"__dataclass__": type(v).__name__, "fields": fields}
        raise TypeError(f"a checkpoint keeps arrays, numbers, strings and {', '.join(types)}, not {type(v).__name__}")

    buffer = io.BytesIO()
    np.savez(
        buffer, key=np.array(key), tree=np.array(json.dumps(tree(value))), **{f"a{i}": a for i, a in enumerate(arrays)}
    )
    data = buffer.getvalue()
    return _LENGTH.pack(len(data)) + data


def decode(data: bytes) -> tuple:
    """(key, value) of one record's archive (without its byte count)."""
    with np.load(io.BytesIO(data), allow_pickle=False) as archive:
        arrays = {name: archive[name] for name in archive.files}
    types = _record_types()

    def back(v):
        if isinstance(v, list):
            return [back(x) for x in v]
        if not isinstance(v, dict):
            return v
        if "__array__" in v:
            return arrays[f"a{v['__array__']}"]
        if "__tuple__" in v:
            return tuple(back(x) for x in v["__tuple__"])
        if "__dict__" in v:
            return {_hashable(back(k)): back(x) for k, x in v["__dict__"]}
        if "__path__" in v:
            return Path(v["__path__"])
        return types[v["__dataclass__"]](**{k: back(x) for k, x in v["fields"].items()})

    return str(arrays["key"]), back(json.loads(str(arrays["tree"])))


def _hashable(key):
    return tuple(_hashable(k) for k in key) if isinstance(key, list | tuple) else key


def read_records(path: Path) -> dict:
    """Every whole record of the file at `path`; one cut short by an interruption, and what follows it, dropped."""
    out, data = {}, path.read_bytes()
    at = 0
    while at + _LENGTH.size <= len(data):
        (size,) = _LENGTH.unpack_from(data, at)
        if at + _LENGTH.size + size > len(data):
            break
        try:
            key, value = decode(data[at + _LENGTH.size : at + _LENGTH.size + size])
        except (ValueError, KeyError, OSError, EOFError, zipfile.BadZipFile):  # a record the interruption garbled
            break
        out[key] = value
        at += _LENGTH.size + size
    return out
