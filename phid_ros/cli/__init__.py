"""The ``phid`` command; entry point ``phid_ros.cli.main:entry``."""
