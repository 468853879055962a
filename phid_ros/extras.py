"""The optional parts of phid_ros, and the one error a missing one gives.

``pip install phid_ros`` carries what every command but ``phid fleet`` needs, numba and comtrade
included. The rest comes with an extra (setup.py's ``extras_require``):

- ``[fleet]``: dask, distributed, bokeh and cloudpickle, for ``phid fleet`` and ``--scheduler``;
- ``[jit]`` (numba) and ``[field]`` (comtrade): in the core install now, kept for install lines
  that name them. Where numba is missing anyway the numpy path gives the same numbers, slower
  (``sim/kernel.py``); where comtrade is, ``phid import-comtrade`` stops with one line.

A command that needs an extra that is not installed stops with one line naming it.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from phid_ros.errors import PhidError

EXTRAS: dict[str, tuple[str, ...]] = {
    "jit": ("numba",),
    "fleet": ("dask", "distributed", "bokeh", "cloudpickle"),
    "field": ("comtrade",),
}
# extras whose modules the core install brings too (kept for the install lines that name them)
IN_CORE = frozenset({"jit", "field"})


class MissingExtraError(PhidError):
    """A command needs an optional dependency that is not installed."""


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """``import module``, or a :class:`MissingExtraError` telling which extra brings it."""
    if module.split(".")[0] not in EXTRAS[extra]:
        raise KeyError(f"{module} is not part of the [{extra}] extra")
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingExtraError(
            f"{purpose} needs {module}, which is not installed ({exc}): pip install 'phid_ros[{extra}]'"
        ) from None


def installed(extra: str) -> bool:
    """Whether every module of ``extra`` is installed (found, not imported: dask's import is slow)."""
    return all(importlib.util.find_spec(module) is not None for module in EXTRAS[extra])
