"""Which recordings belong to which unit: a folder tree or a YAML/CSV list, and each recording's identity.

A folder tree is ``INVENTORY/UNIT/…``: every ``*.mcap`` file, rosbag2 folder (a folder with
``metadata.yaml``) and CSV scenario-set manifest (a ``*.json`` with a ``scenarios`` list, not a
``*.truth.json``) anywhere under a unit's folder is one recording of that unit. A list is a
YAML file (a list of ``{unit, recording}`` or a mapping unit → list of recordings) or a CSV
file with the header ``unit,recording``; relative paths are relative to the list's folder.

A unit may carry its **record on file** (the ``.dyr`` the transmission operator simulates: every
event of its recordings is played into it, as ``phid validate`` plays it) and its **design** (units
of one design, sister units, are compared): in a tree, the one ``*.dyr`` directly in the unit's
folder and a ``design.txt`` there holding the design's name; in a YAML mapping, ``UNIT: {recordings:
[...], record: unit.dyr, design: NAME}``; in a YAML list or a CSV, optional ``record`` and ``design``
keys or columns (one value per unit).

A recording's identity is the SHA-256 of its content (every file of a rosbag2 folder, the
manifest and its CSVs for a scenario set), so a renamed or copied recording is still known
and a rewritten one is new.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from phid_ros.errors import PhidError

LIST_SUFFIXES = (".yaml", ".yml", ".csv")


class InventoryError(PhidError):
    """The inventory cannot be read."""


@dataclass(frozen=True)
class Item:
    unit: str
    path: Path  # absolute: a remote worker reads the same path (a shared file system)
    record: Path | None = None  # the unit's record on file (a .dyr), absolute
    design: str = ""  # sister units share it


DESIGN_FILE = "design.txt"


def discover(inventory: str | Path) -> tuple[list[Item], list[str]]:
    """The recordings of every unit, sorted by unit and path, and warnings (empty units, stray files)."""
    root = Path(inventory)
    if not root.exists():
        raise InventoryError(f"{root}: no such inventory folder or list")
    if root.is_dir():
        items, warnings = _from_tree(root)
    elif root.suffix.lower() in LIST_SUFFIXES:
        items, warnings = _from_list(root)
    else:
        raise InventoryError(f"{root}: an inventory is a folder of unit folders, or a .yaml/.yml/.csv list")
    if not items:
        raise InventoryError(f"{root}: no recordings found (" + ("; ".join(warnings) or "empty") + ")")
    return sorted(items, key=lambda i: (i.unit, str(i.path))), warnings


def _from_tree(root: Path) -> tuple[list[Item], list[str]]:
    items: list[Item] = []
    warnings: list[str] = []
    seen: dict[Path, Path] = {}  # resolved folder or file -> where it was first met
    for entry in sorted(root.iterdir()):
        if entry.name.startswith("."):
            continue
        if entry.is_symlink() and not entry.exists():
            warnings.append(f"{entry}: a dangling link (to {os.readlink(entry)}); skipped")
            continue
        if not entry.is_dir():
            if _is_recording(entry):
                warnings.append(f"{entry}: not inside a unit folder ({root}/UNIT/...); skipped")
            continue
        found = list(_recordings_under(entry, seen, warnings))
        if not found:
            warnings.append(f"unit {entry.name}: no recordings under {entry}")
        record, design = _unit_files(entry)
        items += [Item(entry.name, p.resolve(), record, design) for p in found]
    return items, warnings


def _unit_files(folder: Path) -> tuple[Path | None, str]:
    """A unit folder's record on file (its one ``*.dyr``) and its design (``design.txt``)."""
    records = sorted(p for p in folder.glob("*.dyr") if p.is_file())
    if len(records) > 1:
        names = ", ".join(p.name for p in records)
        raise InventoryError(f"{folder}: {len(records)} records on file ({names}); a unit has one: keep one .dyr")
    design = ""
    if (folder / DESIGN_FILE).is_file():
        design = (folder / DESIGN_FILE).read_text(encoding="utf-8", errors="replace").strip()
    return (records[0].resolve() if records else None), design


def _recordings_under(folder: Path, seen: dict[Path, Path], warnings: list[str]) -> Iterable[Path]:
    """Links are followed once: a folder or file met again (a loop, two links to one recording)
    is named and skipped, so no recording runs twice."""
    real = folder.resolve()
    if real in seen:
        warnings.append(
            f"{folder}: leads to {real}, already listed as {seen[real]} (a link loop or a duplicate); skipped"
        )
        return
    seen[real] = folder
    if (folder / "metadata.yaml").exists():
        yield folder  # a rosbag2 folder: one recording, its .mcap files are its parts
        return
    for entry in sorted(folder.iterdir()):
        if entry.name.startswith("."):
            continue
        if entry.is_symlink() and not entry.exists():
            warnings.append(f"{entry}: a dangling link (to {os.readlink(entry)}); skipped")
        elif entry.is_dir():
            yield from _recordings_under(entry, seen, warnings)
        elif _is_recording(entry):
            target = entry.resolve()
            if target in seen:
                warnings.append(f"{entry}: the same file as {seen[target]}; skipped")
                continue
            seen[target] = entry
            yield entry
        elif entry.name == "manifest.json" or (entry.suffix in (".json", ".mcap") and _empty(entry)):
            warnings.append(f"{entry}: {'empty' if _empty(entry) else 'not a CSV scenario-set manifest'}; skipped")


def _empty(path: Path) -> bool:
    try:
        return path.stat().st_size == 0
    except OSError:
        return False


def _is_recording(path: Path) -> bool:
    if path.suffix == ".mcap" and not path.name.endswith(".partial.mcap"):
        return not _empty(path)  # nothing recorded (a recorder that never wrote): warned by the walk, not a task
    truth = path.name.endswith(".truth.json") or path.name == "truth.json"
    return path.suffix == ".json" and not truth and _is_manifest(path)


def _is_manifest(path: Path) -> bool:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    scenarios = doc.get("scenarios") if isinstance(doc, dict) else None
    return isinstance(scenarios, list) and all(isinstance(s, dict) and "file" in s for s in scenarios)


Entry = tuple[str, str, str, str]  # unit, recording, record on file ("" none), design ("" none)


def _from_list(path: Path) -> tuple[list[Item], list[str]]:
    entries = _read_yaml_list(path) if path.suffix.lower() in (".yaml", ".yml") else _read_csv_list(path)
    items: list[Item] = []
    warnings: list[str] = []
    listed: dict[tuple[str, Path], int] = {}
    of_unit = _unit_keys(path, entries)
    for k, (unit, rec, _, _) in enumerate(entries):
        if not unit or not rec:
            raise InventoryError(f"{path}: entry {k + 1}: needs both a unit and a recording")
        p = _beside(path, rec)
        if p.is_symlink() and not p.exists():  # kept: its row says it failed, so nothing is silently left out
            warnings.append(f"{path}: entry {k + 1}: {rec} is a dangling link (to {os.readlink(p)})")
        key = (unit, p.resolve())
        if key in listed:
            warnings.append(f"{path}: entry {k + 1}: {rec} of {unit} is entry {listed[key]} again; skipped")
            continue
        listed[key] = k + 1
        record, design = of_unit.get(unit, (None, ""))
        items.append(Item(unit, key[1], record, design))
    return items, warnings


def _beside(listing: Path, name: str) -> Path:
    p = Path(name)
    return p if p.is_absolute() else listing.parent / p


def _unit_keys(path: Path, entries: list[Entry]) -> dict[str, tuple[Path | None, str]]:
    """Each unit's record on file and design, one of each per unit (two are refused: which is it?)."""
    found: dict[str, dict[str, str]] = {}
    for k, (unit, _, record, design) in enumerate(entries):
        for key, value in (("record", record), ("design", design)):
            if not value:
                continue
            was = found.setdefault(unit, {}).setdefault(key, value)
            if was != value:
                raise InventoryError(f"{path}: entry {k + 1}: unit {unit} has {key} {value!r} here and {was!r} before")
    out: dict[str, tuple[Path | None, str]] = {}
    for unit, keys in found.items():
        dyr = _beside(path, keys["record"]).resolve() if keys.get("record") else None
        if dyr is not None and not dyr.is_file():
            raise InventoryError(f"{path}: unit {unit}: record on file {dyr}: no such file")
        out[unit] = (dyr, keys.get("design", ""))
    return out


def _read_yaml_list(path: Path) -> list[Entry]:
    from phid_ros.io.files.yaml_doc import YamlDocError, load_yaml

    try:
        doc = load_yaml(path, all_text=True)  # unit 0412 and recording 0412.mcap as written
    except YamlDocError as exc:
        raise InventoryError(str(exc)) from None
    if isinstance(doc, dict):  # unit: [recordings], or unit: {recordings: [...], record: ..., design: ...}
        entries: list[Entry] = []
        for unit, recs in doc.items():
            record = design = ""
            if isinstance(recs, dict):
                unknown = sorted(set(recs) - {"recordings", "record", "design"})
                if unknown:
                    raise InventoryError(
                        f"{path}: unit {unit}: unknown key(s) {', '.join(map(str, unknown))} "
                        "(a unit has recordings, record, design)"
                    )
                record, design = str(recs.get("record") or ""), str(recs.get("design") or "")
                recs = recs.get("recordings")
            if not isinstance(recs, list):
                raise InventoryError(f"{path}: unit {unit}: expected a list of recordings, got {type(recs).__name__}")
            entries += [(str(unit), str(r), record, design) for r in recs]
        return entries
    if isinstance(doc, list) and all(isinstance(e, dict) for e in doc):
        return [_entry(e) for e in doc]
    raise InventoryError(f"{path}: expected a list of {{unit, recording}} or a mapping unit -> recordings")


def _entry(e: dict[str, object]) -> Entry:
    unit, recording, record, design = (str(e.get(k) or "") for k in ("unit", "recording", "record", "design"))
    return unit, recording, record, design


def _read_csv_list(path: Path) -> list[Entry]:
    try:
        with path.open(newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InventoryError(f"{path}: not a readable CSV list ({exc})") from None
    if rows and not {"unit", "recording"} <= set(rows[0]):
        raise InventoryError(f"{path}: header must name 'unit' and 'recording', got {sorted(rows[0])}")
    return [
        (
            (r.get("unit") or "").strip(),
            (r.get("recording") or "").strip(),
            (r.get("record") or "").strip(),
            (r.get("design") or "").strip(),
        )
        for r in rows
    ]
