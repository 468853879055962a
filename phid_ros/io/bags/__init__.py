"""Bags: rosbag2 folders and MCAP files read and written without ROS (rosbags, mcap), and the message schemas.

The names other parts of phid use, importable from here; each module has the rest."""

from __future__ import annotations

from phid_ros.io.bags.cdr_blocks import block_layout, decode_group, stack_by_length
from phid_ros.io.bags.mcap_file import file_metadata, read_mcap_reference
from phid_ros.io.bags.mcap_raw import (
    LOOKAHEAD,
    MAGIC,
    MAX_CHUNK_BYTES,
    McapFormatError,
    WalkStatus,
    iter_message_runs,
    iter_messages,
)
from phid_ros.io.bags.recordings import (
    BackgroundWriter,
    is_mcap_file,
    open_message_writer,
    read_recording,
    recording_source,
    topic_table,
    walked_topic_table,
    write_messages,
    write_recording,
)
from phid_ros.io.bags.rosbag2 import bag_metadata, mcap_storage, read_rosbag2_reference

__all__ = [
    "BackgroundWriter",
    "LOOKAHEAD",
    "MAGIC",
    "MAX_CHUNK_BYTES",
    "McapFormatError",
    "WalkStatus",
    "bag_metadata",
    "block_layout",
    "decode_group",
    "file_metadata",
    "is_mcap_file",
    "iter_message_runs",
    "iter_messages",
    "mcap_storage",
    "open_message_writer",
    "read_mcap_reference",
    "read_recording",
    "read_rosbag2_reference",
    "recording_source",
    "stack_by_length",
    "topic_table",
    "walked_topic_table",
    "write_messages",
    "write_recording",
]
