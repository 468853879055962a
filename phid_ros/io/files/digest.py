"""What a recording is, by content: its files and their SHA-256.

The fleet keys its history on it (the same recording under another name is not identified
twice), and the identification and the diagnosis write it into their results, so that
``phid export`` can refuse to merge the diagnosis of one recording into another's record.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from pathlib import Path

_CHUNK = 1 << 20


def recording_files(path: Path) -> list[Path]:
    """The files whose bytes are the recording, in a fixed order."""
    if path.is_dir():
        return sorted(p for p in path.rglob("*") if p.is_file())
    if path.suffix == ".json":
        files = [path]
        # an unreadable manifest: the import names the problem; its own bytes still identify it
        with contextlib.suppress(OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError):
            doc = json.loads(path.read_text(encoding="utf-8"))
            files += [path.parent / str(s["file"]) for s in doc.get("scenarios", []) if isinstance(s, dict)]
        return files
    return [path]


def content_hash(path: Path) -> str:
    """SHA-256 over the recording's files (relative names and bytes)."""
    h = hashlib.sha256()
    base = path if path.is_dir() else path.parent
    for f in recording_files(path):
        h.update(str(f.relative_to(base) if f.is_relative_to(base) else f.name).encode() + b"\0")
        try:
            with f.open("rb") as fh:
                while chunk := fh.read(_CHUNK):
                    h.update(chunk)
        except OSError:
            h.update(b"<missing>")
        h.update(b"\0")
    return h.hexdigest()


def bytes_hash(path: Path) -> str:
    """SHA-256 over the recording's bytes alone: a single file copied under another name hashes
    alike (:func:`content_hash` names the file, so a copy's differs)."""
    h = hashlib.sha256()
    for f in recording_files(path):
        try:
            with f.open("rb") as fh:
                while chunk := fh.read(_CHUNK):
                    h.update(chunk)
        except OSError:
            h.update(f"<missing {f.name}>".encode())
        h.update(b"\0")
    return h.hexdigest()


def stat_key(path: Path) -> str:
    """Size and modification time of every file: a rehash is needed only when this changes."""
    parts = []
    for f in recording_files(path):
        try:
            st = f.stat()
            parts.append(f"{f}:{st.st_size}:{st.st_mtime_ns}")
        except OSError:
            parts.append(f"{f}:missing")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


def distinct_recordings(paths: list[str]) -> tuple[list[str], list[str]]:
    """The recordings among ``paths`` with distinct content, in order, and a note for each left
    out: the same recording twice (under another name, or a copy) counted as twice the data
    would shrink every std by √2 and turn a withheld parameter into an identified one."""
    first: dict[str, str] = {}
    kept, notes = [], []
    for p in paths:
        digest = bytes_hash(Path(p))
        if digest in first:
            notes.append(f"{p}: the same recording as {first[digest]} (same content); counted once")
            continue
        first[digest] = p
        kept.append(p)
    return kept, notes
