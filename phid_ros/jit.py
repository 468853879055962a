"""numba, where it is installed (the ``[jit]`` extra): one switch for every compiled loop.

Every compiled part of phid (the play-in in ``sim/kernel.py``, the filters in
``compiled_filters.py``) has a numpy path that gives the same numbers; :func:`available` says
which one runs. ``PHID_NO_JIT=1`` forces the numpy path (the tests compare the two).
"""

from __future__ import annotations

import os
from typing import Any

njit: Any
try:
    from numba import njit
except ImportError:  # the numpy paths run instead
    njit = None

# cache: compiled once per machine, not per process; nogil: the diagnosis's job threads run
# compiled play-ins side by side; error_model numpy: a division by zero is inf, as in numpy
OPTIONS: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy"}


def available() -> bool:
    """numba importable and not switched off (``PHID_NO_JIT=1``)."""
    return njit is not None and not os.environ.get("PHID_NO_JIT")


def maybe_jit(f: Any, *, inline: bool = False, cache: bool = True) -> Any:
    """``f`` compiled lazily on first call, or ``f`` itself without numba.

    ``inline``: compiled into each compiled caller (numba's own inlining) instead of called.
    ``cache``: False for a function numba cannot key (a closure over compiled functions).
    """
    if njit is None:
        return f
    return njit(**{**OPTIONS, "cache": cache}, **({"inline": "always"} if inline else {}))(f)


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
