"""``python -m phid_ros``: the ``phid`` command."""

import sys

from phid_ros.cli.main import entry

sys.exit(entry())
