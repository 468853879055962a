"""``phid``: the command line's entry point.

Errors caused by input (missing file, bad column, truncated bag, ...) are
printed on one line as ``phid: error: ...`` with exit status 2, no traceback.
"""

from __future__ import annotations

import gc
import sys
from collections.abc import Sequence

from phid_ros.cli.parser import EXIT_USER_ERROR, build_parser
from phid_ros.cli.tables import make_console
from phid_ros.cluster import one_blas_thread, tune_malloc
from phid_ros.errors import PhidError
from phid_ros.io.files.outputs import CANNOT_WRITE

__all__ = ["EXIT_USER_ERROR", "build_parser", "entry", "main"]


def main(argv: Sequence[str] | None = None) -> int:
    tune_malloc()  # before any thread allocates (see its docstring: the diagnosis's memory, page faults)
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # said by the command's own parser: its name and its --help, not the top level's
        parser.commands[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    console = make_console(wide=args.wide)
    try:
        with one_blas_thread():
            return int(args.func(args, console))
    except PhidError as exc:
        print(f"phid: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    except OSError as exc:
        # a full disk, a read-only or forbidden place met outside an output's own handling (a
        # store, a fleet folder): the machine's, not a bug, so one line and no traceback
        if exc.errno not in CANNOT_WRITE:
            raise
        print(f"phid: error: {exc.filename or 'output'}: {exc.strerror}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("phid: interrupted", file=sys.stderr)
        return 130


def entry() -> int:
    """The ``phid`` command as a process: :func:`main`, then its objects kept out of the
    interpreter's last cyclic collections.

    Why: at exit the interpreter's collector walks every object still alive, and numba's
    compiler alone leaves about a million; that walk took 0.25-0.3 s of a 1.5 s ``phid identify``.
    ``gc.freeze`` moves them to the permanent generation the collector skips; exit handlers,
    flushes and closes run as before (objects are still freed by their reference counts).
    Not done in :func:`main`, which tests and benchmarks call many times in one process.
    """
    code = main()
    gc.freeze()
    return code


if __name__ == "__main__":
    sys.exit(entry())
