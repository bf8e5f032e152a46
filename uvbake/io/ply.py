"""PLY reading (ASCII and binary) into named element arrays, any property layout."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from uvbake.errors import InputError

#: UTF-8 byte-order mark, which some Windows tools write at the start of text files.
BOM = b"\xef\xbb\xbf"

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply_elements(path: str | os.PathLike[str]) -> dict:
    """Parse a PLY file (ASCII or binary, any list lengths) into ``{element: {property: values}}``.

    Scalar properties become arrays; list properties become an (count,k) array when every row has
    the same length, else a list of arrays. This is uvbake's own reader, used when trimesh cannot
    read a file (binary PLY with mixed polygon sizes) or drops a face property.
    """
    fmt, elements, body = _ply_header(path)
    if fmt == "ascii":
        return _ply_ascii(body, elements)
    return _ply_binary(body, elements, "<" if fmt == "binary_little_endian" else ">")


def _ply_header(path, body=True):
    """``(format, [(element, count, [(property, dtype, list item dtype or None)]), body bytes)``; with
    ``body=False`` the file is read only up to its header (the body is ``b""``)."""
    with open(path, "rb") as f:
        lines: list[str] = []
        while True:
            raw = f.readline()
            if not raw:
                raise ValueError("no end_header line")
            if not lines and raw.startswith(BOM):
                raw = raw[len(BOM):]
            line = raw.decode("ascii", "replace").strip()
            lines.append(line)
            if line == "end_header":
                break
        data = f.read() if body else b""
    if not lines or lines[0] != "ply":
        raise ValueError("does not start with 'ply'")
    fmt = None
    elements: list[tuple[str, int, list[tuple[str, str, str | None]]]] = []
    for line in lines[1:]:
        parts = line.split()
        if parts[:1] == ["format"]:
            fmt = parts[1]
        elif parts[:1] == ["element"]:
            elements.append((parts[1], int(parts[2]), []))
        elif parts[:1] == ["property"]:
            if parts[1] == "list":
                elements[-1][2].append((parts[4], _PLY_TYPES[parts[2]], _PLY_TYPES[parts[3]]))
            else:
                elements[-1][2].append((parts[2], _PLY_TYPES[parts[1]], None))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ValueError(f"unknown format {fmt!r}")
    return fmt, elements, data


def check_ply_complete(path: str | os.PathLike[str], name: str) -> None:
    """Raise InputError if the file holds fewer elements than its header declares (truncated)."""
    try:
        fmt, elements, body = _ply_header(path)
    except (ValueError, KeyError, IndexError):
        return                                 # not ours to judge: the reader reports it
    declared = ", ".join(f"{count} {el}" for el, count, _ in elements)
    fix = "the file is truncated; export or copy it again"
    if fmt == "ascii":
        rows = sum(1 for line in body.split(b"\n") if line.strip())
        if rows < sum(count for _, count, _ in elements):
            raise InputError(f"{name}: cannot read as PLY: the header declares {declared} but the file holds only {rows} "
                             f"data lines; {fix}")
        return
    endian = "<" if fmt == "binary_little_endian" else ">"
    try:
        _ply_binary(body, elements, endian)
    except (ValueError, IndexError) as exc:
        raise InputError(f"{name}: cannot read as PLY: the header declares {declared} but the data ends early "
                         f"({exc}); {fix}") \
            from None


def _ply_ascii(body: bytes, elements: list[Any]) -> dict:
    tokens = body.split()
    pos, out = 0, {}
    for name, count, props in elements:
        columns: dict[str, list[Any]] = {p[0]: [] for p in props}
        for _ in range(count):
            for prop, dtype, item in props:
                if item is None:
                    columns[prop].append(tokens[pos])
                    pos += 1
                else:
                    k = int(tokens[pos])
                    columns[prop].append(np.array(tokens[pos + 1: pos + 1 + k], dtype=float).astype(item))
                    pos += 1 + k
        out[name] = {p[0]: _ply_column(columns[p[0]], p) for p in props}
    return out


def _ply_binary(body: bytes, elements: list[Any], endian: str) -> dict:
    pos, out = 0, {}
    for name, count, props in elements:
        fixed: list[Any] = []  # try one record layout, using the first row's list lengths
        probe = pos
        for prop, dtype, item in props:
            if item is None:
                fixed.append((prop, endian + dtype))
                probe += np.dtype(dtype).itemsize
            else:
                k = int(np.frombuffer(body, endian + dtype, 1, probe)[0]) if count else 0
                fixed += [(f"{prop}__n", endian + dtype), (prop, endian + item, (k,))]
                probe += np.dtype(dtype).itemsize + k * np.dtype(item).itemsize
        layout = np.dtype(fixed)
        if pos + count * layout.itemsize <= len(body):
            data = np.frombuffer(body, layout, count, pos)
            lists = [p[0] for p in props if p[2] is not None]
            if all(np.all(data[f"{p}__n"] == data.dtype[p].shape[0]) for p in lists):
                out[name] = {p[0]: np.array(data[p[0]]) for p in props}
                pos += count * layout.itemsize
                continue
        columns: dict[str, list[Any]] = {p[0]: [] for p in props}  # rows of different lengths: walk them
        for _ in range(count):
            for prop, dtype, item in props:
                size = np.dtype(dtype).itemsize
                value = np.frombuffer(body, endian + dtype, 1, pos)[0]
                pos += size
                if item is None:
                    columns[prop].append(value)
                else:
                    k = int(value)
                    columns[prop].append(np.frombuffer(body, endian + item, k, pos).copy())
                    pos += k * np.dtype(item).itemsize
        out[name] = {p[0]: _ply_column(columns[p[0]], p) for p in props}
    return out


def _ply_column(values, prop):
    name, dtype, item = prop
    if item is None:
        return np.array(values).astype(dtype)
    if values and all(len(v) == len(values[0]) for v in values):
        return np.array(values, dtype=item).reshape(len(values), -1)
    return values


def _ply_face_property_names(path: str | os.PathLike[str]) -> list[str]:
    names, in_face = [], False
    with open(path, "rb") as f:
        for raw_line in f:
            parts = raw_line.decode("ascii", "replace").split()
            if parts[:1] == ["end_header"]:
                break
            if parts[:1] == ["element"]:
                in_face = parts[1:2] == ["face"]
            elif parts[:1] == ["property"] and in_face:
                names.append(parts[-1])
    return names
