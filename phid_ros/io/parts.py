"""A recording read in consecutive parts, for commands that play it through once.

``phid replay`` and ``phid track`` feed the online pipeline in file order and keep only what the
pipeline keeps (its ring buffer, the windows, the tracker's state); reading the whole file
first held every sample of it (0.5 GB per hour of 1 kHz data). :func:`recording_parts` walks the
file as :func:`phid_ros.io.bags.recordings.read_recording` does, by the same MCAP walker and the same
assembly, but hands over a :class:`~phid_ros.io.recording.Recording` every ``part_messages``
messages. A part's samples keep their positions in the file (``msg_seq``), so a player that
takes the parts in turn feeds the pipeline the very sequence the whole recording would.

Where the fast walker does not apply (a rosbag2 folder in SQLite or compressed storage), the
recording is read whole and handed over as one part.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from phid_ros.errors import BagError
from phid_ros.io.recording import (
    STREAM_NAMES,
    Recording,
    checked_payloads,
    is_phid_topic,
    recording_from_raw,
)

PART_MESSAGES = 6000  # 150 s of a 1 kHz recording in 100-sample blocks on four streams: ~20 MB a part


class RecordingParts:
    """The parts of one recording, its metadata, and how far the walk has got.

    Iterate once. ``metadata`` is known before the first part; ``warnings`` (a file cut short)
    after the last; ``fraction`` is the share of the file's bytes walked so far.
    """

    def __init__(self, path: str | Path, part_messages: int = PART_MESSAGES) -> None:
        from phid_ros.io.bags.mcap_raw import WalkStatus

        self.path = Path(path)
        self.source = str(path)
        self.part_messages = part_messages
        self.warnings: list[str] = []
        self.metadata: dict[str, str] = {}
        self._files: list[Path] = []
        self._statuses: dict[Path, WalkStatus] = {}
        self._whole: Recording | None = None
        self.seen: set[str] = set()
        self._span: tuple[int, int] | None = None
        self._plan()

    def _plan(self) -> None:
        from phid_ros.io.bags.mcap_raw import WalkStatus
        from phid_ros.io.bags.recordings import is_mcap_file, read_recording

        p = self.path
        if not p.exists():
            raise BagError(f"{p}: no such bag or MCAP file")
        files: list[Path] | None = None
        if p.is_dir():
            files = _rosbag2_mcap_files(p, self.metadata)
        elif p.suffix == ".json":  # a CSV scenario set (its manifest): small, read whole as one part
            from phid_ros.io.csvset.csv_import import import_csv_set

            self._whole = import_csv_set(p)
            self.metadata = dict(self._whole.metadata)
            self.warnings += self._whole.warnings
            return
        elif is_mcap_file(p):
            from phid_ros.io.bags.mcap_file import file_metadata

            files = [p]
            # a file cut before its summary: read what is there, the walk says how much
            with contextlib.suppress(BagError):
                self.metadata.update(file_metadata(p))
        else:
            raise BagError(f"{p}: not a rosbag2 folder or .mcap file")
        if files is None:  # storage the walker does not read: whole, as one part
            self._whole = read_recording(p)
            self.metadata = dict(self._whole.metadata)
            return
        self._files = files
        self._statuses = {f: WalkStatus() for f in files}

    def marker_count(self) -> int | None:
        """Scenario markers in the recording, from its summary (an MCAP file's statistics, a bag's
        metadata.yaml) without walking it; None when no summary says (a file cut short)."""
        from phid_ros.io.topics import SCENARIO_TOPIC

        if self._whole is not None:
            return len(self._whole.scenarios)
        if self.path.is_dir():
            from phid_ros.io.bags.rosbag2 import bag_metadata

            try:
                topics = bag_metadata(self.path).get("topics_with_message_count") or []
                return sum(int(t["message_count"]) for t in topics if t["topic_metadata"]["name"] == SCENARIO_TOPIC)
            except (KeyError, TypeError, ValueError, OSError):
                return None
        from mcap.reader import make_reader

        try:
            with self.path.open("rb") as fh:
                summary = make_reader(fh).get_summary()
        except Exception:  # noqa: BLE001 (the mcap reader raises assorted errors on a file cut short)
            return None
        if summary is None or summary.statistics is None:
            return None
        counts = summary.statistics.channel_message_counts
        return sum(counts.get(i, 0) for i, c in summary.channels.items() if c.topic == SCENARIO_TOPIC)

    @property
    def span_ns(self) -> tuple[int, int]:
        """The first and the last sample's stamp of the parts walked so far ((0, 0) before any)."""
        return self._span or (0, 0)

    def _spanned(self, rec: Recording) -> None:
        if any(len(s) for s in rec.streams.values()):
            lo, hi = rec.span_ns()
            self._span = (lo, hi) if self._span is None else (min(lo, self._span[0]), max(hi, self._span[1]))

    def _walked(self) -> int:
        return sum(st.read_to for st in self._statuses.values())

    @property
    def fraction(self) -> float:
        """Share of the recording's bytes walked so far (0 to 1)."""
        total = sum(st.size for st in self._statuses.values())
        done = sum(st.read_to for st in self._statuses.values())
        return done / total if total else 0.0

    def __iter__(self) -> Iterator[Recording]:
        if self._whole is not None:
            self.seen.update(self._whole.streams)
            self._spanned(self._whole)
            yield self._whole
            return
        from phid_ros.io.bags.mcap_raw import McapFormatError, iter_message_runs

        def items() -> Iterator[tuple]:
            first = 0
            for f in self._files:
                yield from checked_payloads(iter_message_runs(f, self._statuses[f], first), self.source)
                first += self._statuses[f].messages

        group: list[tuple] = []
        count = 0
        parts = 0
        last = -1
        try:
            for item in items():
                # a part ends only where a chunk does: a chunk's messages come as runs whose positions
                # interleave, and a part must hold every message before its last one (the walker has
                # moved on to the next chunk when the bytes walked change)
                walked = self._walked()
                if count >= self.part_messages and walked != last:
                    yield self._part(group)
                    parts += 1
                    group, count = [], 0
                last = walked
                if not is_phid_topic(item[0]):
                    continue
                group.append(item)
                raw = item[2]
                count += len(raw) if isinstance(raw, np.ndarray) else 1
            if group or not parts:
                yield self._part(group)
        except McapFormatError as exc:
            raise BagError(f"{self.source}: truncated or corrupt recording: {exc}") from exc
        missing = [s for s in STREAM_NAMES if s not in self.seen]
        if missing:
            present = ", ".join(sorted(self.seen)) or "none"
            raise BagError(f"{self.source}: no messages on the sensor stream(s) {missing} (streams present: {present})")
        for f, st in self._statuses.items():
            cut = st.truncation()
            if cut:
                self.warnings.append(f"{f}: {cut}")

    def _part(self, group: list[tuple]) -> Recording:
        if not group:
            raise BagError(f"{self.source}: none of the phid sensor topics found")
        rec = recording_from_raw(group, source=self.source, metadata=self.metadata, required=())
        self.seen.update(rec.streams)
        self._spanned(rec)
        return rec


def _rosbag2_mcap_files(path: Path, metadata: dict[str, str]) -> list[Path] | None:
    """The storage files of a rosbag2 folder the walker reads, its phid metadata into ``metadata``."""
    from phid_ros.io.bags.rosbag2 import mcap_storage

    if not (path / "metadata.yaml").is_file():
        raise BagError(f"{path}: not a rosbag2 folder (metadata.yaml missing)")
    storage = mcap_storage(path)
    if storage is None:
        return None
    metadata.update(storage[1])
    return storage[0]


def recording_parts(path: str | Path, part_messages: int = PART_MESSAGES) -> RecordingParts:
    """The recording at ``path`` (rosbag2 folder or .mcap) in parts of about ``part_messages`` messages."""
    return RecordingParts(path, part_messages)
