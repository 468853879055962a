"""Output files: never half-written, never over an input, replaced only when that is safe.

Every file or bag a command writes goes first to a ``.partial`` name beside its final
place and is renamed when complete (a rename within one folder is atomic), so a crash
or Ctrl-C leaves either the old file or the new one, never a torn one. An output that
is also one of the command's inputs (``--json`` over the ``--truth`` file, a report over
the manifest) is refused before any work starts.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from phid_ros.errors import PhidError


class OutputError(PhidError):
    """An output path cannot be written as asked."""


PARTIAL = ".partial"


def partial_path(path: str | Path) -> Path:
    """Where an output is built: ``x.mcap`` -> ``x.partial.mcap``, a folder ``x`` -> ``x.partial``."""
    p = Path(path)
    return p.with_name(p.stem + PARTIAL + p.suffix) if p.suffix else p.with_name(p.name + PARTIAL)


def final_name(name: str) -> str:
    """The name an output built under :func:`partial_path`'s folder name will have."""
    return name.removesuffix(PARTIAL)


def _same(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and os.path.samefile(a, b))
    except OSError:
        return False


def refuse_inputs(outputs: Iterable[str | Path | None], inputs: Iterable[str | Path | None]) -> None:
    """An output that is an input, lies inside an input folder, or is a file an input manifest
    names (a CSV of the set), is refused (before any work)."""
    from phid_ros.io.files.digest import recording_files

    ins = [f for i in inputs if i for f in (recording_files(Path(i)) if str(i).endswith(".json") else [Path(i)])]
    for o in outputs:
        if not o:
            continue
        out = Path(o)
        for i in ins:
            inside = i.is_dir() and out.resolve().is_relative_to(i.resolve())
            if _same(out, i) or inside:
                raise OutputError(f"{out}: is an input of this command ({i}); refusing to overwrite it")
        if not out.resolve().parent.is_dir():
            raise OutputError(f"{out}: the folder {out.parent} does not exist")


def remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()


@contextmanager
def atomic_output(path: str | Path, *, keep_partial: bool = False) -> Iterator[Path]:
    """Yield the ``.partial`` path to write; on success it replaces ``path``.

    On failure the partial output is removed, or kept with ``keep_partial`` (a replay's
    output up to an interruption is worth keeping; the caller says where it is).
    """
    final = Path(path)
    tmp = partial_path(final)
    try:
        remove(tmp)  # a leftover of an earlier killed run of ours
        try:
            yield tmp
        except BaseException:
            if not keep_partial:
                _remove_quietly(tmp)
            raise
        if final.is_dir() and not final.is_symlink():
            shutil.rmtree(final)
        os.replace(tmp, final)
    except OSError as exc:
        if exc.errno not in CANNOT_WRITE or not _concerns(exc, final, tmp):
            raise
        if not keep_partial:
            _remove_quietly(tmp)
        raise OutputError(f"{final}: {exc.strerror}; {_what_is_kept(final, tmp, keep_partial)}") from None


# the write failures that are the machine's, not a bug: a full disk or quota, a read-only or
# forbidden place. They are one line naming the path, never a traceback.
CANNOT_WRITE = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM})


def _concerns(exc: OSError, final: Path, tmp: Path) -> bool:
    """Whether the failure is the output's (a writer's error often names no file) and not an
    input's that happened to be read while the output was being written."""
    if exc.filename is None:
        return True
    name = str(exc.filename)
    return any(name.startswith(str(p)) for p in (tmp, final, final.parent.resolve())) or Path(name).parent in (
        final.parent,
        final.parent.resolve(),
    )


def _what_is_kept(final: Path, tmp: Path, keep_partial: bool) -> str:
    if keep_partial and tmp.exists():
        return f"what was written before it is kept in {tmp}"
    if final.exists():
        return f"nothing written, the earlier {final.name} is unchanged"
    return "nothing written"


def _remove_quietly(path: Path) -> None:
    # on a read-only or full disk the partial output may not even be removable
    with contextlib.suppress(OSError):
        remove(path)


def write_text(path: str | Path, text: str) -> Path:
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
