"""Trust and integrity of what the cache holds, for the build and for ``gs.load``.

A cache directory can be shared by mistake (``GRASPING_SYM_CACHE=/tmp/...``) or tampered
with. What is loaded from it runs as code (a compiled library is dlopened; CasADi dlopens what
a serialized ``External`` names), so nothing is read from, written through or loaded from a
cache entry unless:

- it is a real directory or regular file, not a symbolic link;
- the current user owns it;
- neither its group nor others may write it.

A violation raises :class:`UnsafeCacheError`, naming the path, what is wrong and how to fix
it (use a private cache: ``chmod go-w``, or another ``GRASPING_SYM_CACHE``).

Files are written atomically and never through a link: into a fresh temporary file opened with
``O_CREAT | O_EXCL | O_NOFOLLOW`` in the target's directory, then renamed over the target
(a rename replaces a link itself, never what it points to). A compiled library's SHA-256 is
kept in its manifest and checked before every load (:func:`library_problem`).
"""
from __future__ import annotations

import errno
import fcntl
import hashlib
import os
import shutil
import stat
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from grasping_sym.errors import CacheWriteError, CorruptCacheError, UnsafeCacheError

__all__ = ["CacheWriteError", "CorruptCacheError", "UnsafeCacheError", "check_file",
           "check_tree", "clean_stale", "ensure_dir", "exclusive", "is_temporary", "library_problem",
           "sha256_file", "write_bytes", "write_text"]

#: Temporary files and directories of an interrupted build older than this (s) are removed.
STALE_AFTER = 3600.0
#: Name prefixes of the temporaries the build leaves in a cache directory while it works.
_TEMP_MARKERS = (".build-", ".tmp", ".links-", ".write-")


def _problem(st: os.stat_result, want_dir: bool) -> str | None:
    if stat.S_ISLNK(st.st_mode):
        return "it is a symbolic link"
    if want_dir and not stat.S_ISDIR(st.st_mode):
        return "it is not a directory"
    if not want_dir and not stat.S_ISREG(st.st_mode):
        return "it is not a regular file"
    if hasattr(os, "geteuid") and st.st_uid != os.geteuid():
        return f"it belongs to user id {st.st_uid}, not to you ({os.geteuid()})"
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"its group or others may write it (mode {stat.S_IMODE(st.st_mode):o})"
    return None


def check_file(path: Path) -> None:
    """Raise :class:`UnsafeCacheError` unless ``path`` is a regular file that is yours alone."""
    problem = _problem(os.lstat(path), want_dir=False)
    if problem:
        raise UnsafeCacheError(path, problem)


def check_dir(path: Path) -> None:
    """Raise :class:`UnsafeCacheError` unless ``path`` is a directory that is yours alone."""
    problem = _problem(os.lstat(path), want_dir=True)
    if problem:
        raise UnsafeCacheError(path, problem)


def ensure_dir(path: Path, root: Path | None = None) -> Path:
    """``path`` as a directory that is yours alone: created (mode 0700, with its missing
    parents up to ``root``) when missing, else checked; so is every directory between ``root``
    and ``path``."""
    path = Path(path)
    chain = [path]
    if root is not None:
        root = Path(root)
        rel = path.relative_to(root)
        chain = [root / Path(*rel.parts[:k]) for k in range(len(rel.parts) + 1)]
    for d in chain:
        try:
            os.mkdir(d, 0o700)
        except FileExistsError:
            check_dir(d)
        except FileNotFoundError:
            os.makedirs(d, 0o700, exist_ok=True)
            check_dir(d)
        except OSError as exc:
            raise CacheWriteError(d, exc) from exc
    return path


def check_tree(directory: Path, names) -> None:
    """Check ``directory`` and each of its files ``names`` that exists (see the module's
    docstring)."""
    check_dir(directory)
    for n in names:
        p = Path(directory) / n
        if os.path.lexists(p):
            check_file(p)


def write_bytes(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically, never through a link (see the module's
    docstring)."""
    path = Path(path)
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{time.monotonic_ns()}")
    try:
        fd = os.open(tmp, flags, 0o644)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
        except BaseException:
            os.unlink(tmp)
            raise
        os.replace(tmp, path)
    except OSError as exc:
        if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM):
            raise CacheWriteError(path, exc) from exc
        raise
    return path


@contextmanager
def exclusive(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on the file ``path`` (created if missing, never through a
    link, checked as the cache's files are) for the ``with`` block: one process or thread at
    a time compiles what the others then find done. ``flock``: the system releases it when
    the holder ends, however it ends. The file is never replaced (a replaced lock file would
    let two holders lock two files)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o600)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise UnsafeCacheError(path, "it is a symbolic link") from None
        raise
    try:
        if (problem := _problem(os.fstat(fd), want_dir=False)) is not None:
            raise UnsafeCacheError(path, problem)
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def write_text(path: Path, text: str) -> Path:
    return write_bytes(path, text.encode())


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def library_problem(lib: Path, manifest: dict) -> str | None:
    """Why the library ``lib`` must not be loaded (None: it may): missing, no recorded
    checksum, or a checksum that differs from the one recorded when it was compiled (a
    truncated or altered file). Raises :class:`UnsafeCacheError` when it is not yours alone:
    that is refused, never rebuilt over."""
    if not os.path.lexists(lib):
        return f"{lib} is missing"
    check_file(lib)
    want = manifest.get("libraries", {}).get(Path(lib).name)
    if not isinstance(want, str):
        return f"{lib} has no checksum in its manifest"
    got = sha256_file(lib)
    if got != want:
        return f"{lib} is damaged: its SHA-256 is {got[:16]}..., the manifest recorded {want[:16]}..."
    return None


def is_temporary(name: str) -> bool:
    """Whether ``name`` is that of a temporary an (interrupted) build leaves in a cache
    directory while it works (a dot, then one of the markers of ``_TEMP_MARKERS``)."""
    return name.startswith(".") and any(m in name for m in _TEMP_MARKERS)


def clean_stale(directory: Path, max_age: float = STALE_AFTER) -> list[str]:
    """Remove the temporaries an interrupted build left in ``directory`` (names starting with
    a dot and holding a temporary marker, older than ``max_age`` seconds); return their names."""

    removed = []
    now = time.time()
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for e in entries:
        if not e.name.startswith(".") or not any(m in e.name for m in _TEMP_MARKERS):
            continue
        try:
            st = e.stat(follow_symlinks=False)
            if now - st.st_mtime < max_age or st.st_uid != os.geteuid():
                continue
            if e.is_dir(follow_symlinks=False):
                shutil.rmtree(e.path, ignore_errors=True)
            else:
                os.unlink(e.path)
            removed.append(e.name)
        except OSError:
            continue
    return removed
