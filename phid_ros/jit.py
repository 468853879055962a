"""numba, where it is installed (the ``[jit]`` extra): one switch for every compiled loop.

Every compiled part of phid (the play-in in ``sim/kernel.py``, the filters in
``compiled_filters.py``) has a numpy path that gives the same numbers; :func:`available` says
which one runs. ``PHID_NO_JIT=1`` forces the numpy path (the tests compare the two).
"""

from __future__ import annotations

import importlib.util
import os
import threading
from functools import cache
from typing import Any


@cache
def _installed() -> bool:
    # found, not imported: importing numba takes over a second, which a command that compiles
    # nothing (``phid --help``, ``phid info``) should not pay
    return importlib.util.find_spec("numba") is not None


def njit(*args: Any, **kwargs: Any) -> Any:
    """numba's ``njit``, numba imported on the first use (see :func:`available`)."""
    from numba import njit as numba_njit

    return numba_njit(*args, **kwargs)


# cache: compiled once per machine, not per process; nogil: the diagnosis's job threads run
# compiled play-ins side by side; error_model numpy: a division by zero is inf, as in numpy
OPTIONS: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy"}


def available() -> bool:
    """numba importable and not switched off (``PHID_NO_JIT=1``)."""
    return _installed() and not os.environ.get("PHID_NO_JIT")


def maybe_jit(f: Any, *, inline: bool = False, cache: bool = True) -> Any:
    """``f`` compiled lazily on first call, or ``f`` itself without numba.

    ``inline``: compiled into each compiled caller (numba's own inlining) instead of called.
    ``cache``: False for a function numba cannot key (a closure over compiled functions).
    """
    if not _installed():
        return f
    return njit(**{**OPTIONS, "cache": cache}, **({"inline": "always"} if inline else {}))(f)


class _OnFirstCall:
    """A loop compiled the first time it is called (from Python, never from compiled code)."""

    def __init__(self, f: Any) -> None:
        self.f = self.py_func = f  # py_func: the Python loop, under numba's dispatcher's name for it
        self.compiled: Any = None
        self.lock = threading.Lock()  # the recalibration's worker and the main thread may both call first
        self.__doc__, self.__name__ = f.__doc__, f.__name__

    def __call__(self, *args: Any) -> Any:
        if self.compiled is None:
            with self.lock:
                if self.compiled is None:
                    self.compiled = njit(**OPTIONS)(self.f)
        return self.compiled(*args)


def jit_on_first_call(f: Any) -> Any:
    """``f`` compiled on its first call, numba imported then, or ``f`` itself without numba. For
    a loop only Python calls (a compiled caller needs :func:`maybe_jit`'s dispatcher): importing
    its module then costs no numba (the control models, read by the command line's parser)."""
    return _OnFirstCall(f) if _installed() else f


def f64(dims: int, readonly: bool = False) -> Any:
    """A float64 array of any layout, for an explicit signature. Loops' inputs are typed
    read-only: that type accepts writable arrays too (not the other way round)."""
    from numba import types

    return types.Array(types.float64, dims, "A", readonly=readonly)


def i64(dims: int, readonly: bool = False) -> Any:
    """An int64 array of any layout, for an explicit signature (see :func:`f64`)."""
    from numba import types

    return types.Array(types.int64, dims, "A", readonly=readonly)


def compile_once(f: Any, *arg_types: Any, cache: bool = True) -> Any:
    """``f`` compiled for exactly these argument types (any layout, read-only inputs: see
    :func:`f64`), loaded from numba's cache where it was compiled before.

    Why: left to numba, every combination of layouts and write flags the callers happen to
    pass compiles its own copy; the play-in met eight, at 10-20 s each, on a first diagnosis.
    """
    return njit(tuple(arg_types), **{**OPTIONS, "cache": cache})(f)
