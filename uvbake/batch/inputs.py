"""What a batch works on: the assets named by files, folders and manifests, and the key of each.

    assets = collect(["scans/", "extra.ply", "list.csv"], out_dir="out")

Inputs:
- a mesh file (one of :data:`uvbake.io.MESH_EXTENSIONS`);
- a folder, searched recursively for those extensions (hidden entries and ``out_dir`` are skipped);
- a manifest: ``.txt`` (one path per line; blank lines and ``#`` comments ignored) or ``.csv`` with a
  ``path`` column and an optional ``timeout_s`` column (a per-asset time limit). Relative paths in a
  manifest are relative to the manifest's folder.

Every asset gets an id (its path relative to the folder it was found in, without the extension, with
``/`` kept), which names its output folder ``OUT/assets/<id>/``. Two inputs with the same id get the
first 8 hex digits of their absolute path's hash appended, so ids are unique and do not depend on the
order of discovery. The same file named twice is one asset.

Keys: ``key = sha256(input bytes) + sha256(normalised options)``; an asset is redone exactly when its
key differs from the one recorded in its completion marker.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from uvbake.errors import InputError
from uvbake.io.formats import MESH_EXTENSIONS

MANIFEST_EXTENSIONS = (".txt", ".csv")


@dataclass(frozen=True)
class Asset:
    """One input mesh of a batch."""

    id: str                       # output folder name under OUT/assets/, unique in the batch
    path: Path                    # absolute path of the mesh
    timeout_s: float | None = None  # per-asset time limit from a manifest (None: the batch's)


def collect(inputs: Any, *, out_dir: str | os.PathLike[str] | None = None) -> list:
    """The assets named by ``inputs`` (files, folders, manifests), sorted by id.

    Raises
    ------
    InputError
        A path does not exist, has an unknown extension, a manifest row is malformed, or nothing was found.
    """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    out = Path(out_dir).resolve() if out_dir is not None else None
    found: dict[Path, tuple[str, float | None]] = {}   # absolute path -> (id, timeout_s); the first mention wins
    for item in inputs:
        path = Path(item)
        if not path.exists():
            raise InputError(f"input {item} does not exist; check the path")
        if path.is_dir():
            entries = _walk(path, out)
            if not entries:
                raise InputError(f"input folder {item} holds no mesh ({', '.join(MESH_EXTENSIONS)}); "
                                 "check the folder")
            for p in entries:
                found.setdefault(p.resolve(), (_id(p.relative_to(path)), None))
        elif path.suffix.lower() in MANIFEST_EXTENSIONS:
            for p, timeout in _manifest(path):
                found.setdefault(p.resolve(), (_id(Path(p.name)), timeout))
        elif path.suffix.lower() in MESH_EXTENSIONS:
            found.setdefault(path.resolve(), (_id(Path(path.name)), None))
        else:
            raise InputError(f"input {item} is neither a mesh ({', '.join(MESH_EXTENSIONS)}), a folder nor a "
                             f"manifest ({', '.join(MANIFEST_EXTENSIONS)}); rename it or list it in a manifest")
    if not found:
        raise InputError("no inputs given; pass mesh files, folders or a manifest")
    counts: dict[str, int] = {}
    for ident, _ in found.values():
        counts[ident] = counts.get(ident, 0) + 1
    assets = []
    for p, (ident, timeout) in found.items():
        if counts[ident] > 1:
            ident = f"{ident}-{hashlib.sha256(str(p).encode()).hexdigest()[:8]}"
        assets.append(Asset(ident, p, timeout))
    return sorted(assets, key=lambda a: a.id)


def _walk(folder: Path, out: Path | None) -> list:
    hits = []
    for name, dirs, files in os.walk(folder):
        root = Path(name)
        # never descend into the batch's own output (its .obj files would become inputs) or hidden folders
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and (out is None or (root / d).resolve() != out))
        hits += [root / f for f in sorted(files) if not f.startswith(".") and Path(f).suffix.lower() in MESH_EXTENSIONS]
    return hits


def _id(rel: Path) -> str:
    """Output folder name: the relative path without extension, in characters safe on every filesystem."""
    text = rel.with_suffix("").as_posix()
    return "".join(c if c.isalnum() or c in "-_./" else "_" for c in text).strip("./") or "mesh"


def _manifest(path: Path) -> list:
    base = path.parent
    rows: list[tuple[int, str, float | None]] = []
    if path.suffix.lower() == ".txt":
        for n, line in enumerate(path.read_text().splitlines(), 1):
            line = line.split("#", 1)[0].strip()
            if line:
                rows.append((n, line, None))
    else:
        with open(path, newline="") as fh:
            reader = csv.DictReader(fh)
            if not reader.fieldnames or "path" not in reader.fieldnames:
                raise InputError(f"manifest {path} has no 'path' column; its first row must name the columns "
                                 "(path[,timeout_s])")
            for n, row in enumerate(reader, 2):
                text = (row.get("timeout_s") or "").strip() or None
                timeout: float | None = None
                if text is not None:
                    try:
                        timeout = float(text)
                    except ValueError:
                        timeout = -1.0
                    if not timeout > 0:
                        raise InputError(f"manifest {path} line {n}: timeout_s {row['timeout_s']!r} must be a "
                                         "positive number of seconds")
                rows.append((n, (row["path"] or "").strip(), timeout))
    out = []
    for n, name, timeout in rows:
        p = Path(name)
        p = p if p.is_absolute() else base / p
        if not p.is_file():
            raise InputError(f"manifest {path} line {n}: {name} does not exist; fix the path (relative paths "
                             "are relative to the manifest's folder)")
        if p.suffix.lower() not in MESH_EXTENSIONS:
            raise InputError(f"manifest {path} line {n}: {name} is not a mesh ({', '.join(MESH_EXTENSIONS)})")
        out.append((p, timeout))
    return out


def file_hash(path: str | os.PathLike[str]) -> str:
    """sha256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def options_hash(options: dict) -> str:
    """sha256 of the normalised options (sorted keys, canonical JSON; floats by their shortest repr)."""
    text = json.dumps(options, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()
