"""Which code made a number: the release, and a digest of the code that computes it.

The release (``__version__``) changes when we publish; the *method version* changes whenever
an identification's numbers can: it is the release plus a digest of the source of every
package that reads, aligns, cuts, identifies or diagnoses (everything but the command line's
presentation, the ROS shells, the fleet's driver and the exporters). ``phid fleet`` keys its
history on it, so after any such change a rerun identifies again what an older method
identified (issue 37: a rerun used to keep the old numbers), and a Dask worker running other
code is refused. Conservative by design: an edited comment also counts as a change.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

from phid_ros import __version__

# the parts whose code cannot change a number: presentation, wiring, and the fleet's bookkeeping
NOT_NUMERIC = ("cli", "nodes", "fleet", "export", "msg_schemas_data")


@lru_cache(maxsize=1)
def method_version() -> str:
    """``0.2.0+<12 hex digits>``; just the release where the sources are not installed as files."""
    root = Path(__file__).resolve().parent
    sources = sorted(p for p in root.rglob("*.py") if p.relative_to(root).parts[0] not in NOT_NUMERIC)
    if not sources:
        return __version__
    digest = hashlib.sha256()
    for path in sources:
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return f"{__version__}+{digest.hexdigest()[:12]}"
