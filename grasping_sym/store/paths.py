"""Content hash of a scene's generated code, and where generated code lives.

- Built-in scenes: ``<repository>/generated/<name>/`` (committed C + manifest), installed as
  the package data ``grasping_sym.generated``.
- Every built model: ``<cache root>/<name>-<hash16>/`` with the C, the manifest and the
  compiled library. The cache root is ``$GRASPING_SYM_CACHE`` if set, else
  ``$XDG_CACHE_HOME/grasping_sym`` (default ``~/.cache/grasping_sym``).

The hash covers the scene's canonical text, the package version, CasADi's version and the
package's source tree read whole (``tree_digest``), so any change to one of them makes a
fresh build; the compiler and its flags are checked against the library's record.
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import stat
import sys
from collections.abc import Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from functools import lru_cache
from importlib.resources import files
from pathlib import Path

from grasping_sym.errors import CacheContentsError, SourcesChangedError
from grasping_sym.store import files as stored
from grasping_sym.store import safety

PACKAGE_DIR = Path(__file__).resolve().parent.parent


def generated_dir() -> Path:
    """The committed generated code: the package data ``grasping_sym.generated`` (the
    repository's top-level ``generated/`` in a source checkout or an editable install)."""

    return Path(str(files("grasping_sym.generated")))


def source_checkout() -> Path | None:
    """The repository root when the package runs from a source checkout (``generated/`` and
    ``pyproject.toml`` beside the package), else None (an installed copy)."""
    root = PACKAGE_DIR.parent
    if (root / "pyproject.toml").is_file() and generated_dir().resolve() == (root / "generated").resolve():
        return root
    return None
#: The floors above the build (``docs/architecture.md``): the layers contract in
#: ``pyproject.toml`` forbids every module below them to import them, so they cannot shape
#: generated code, and their text stays out of the code's hash. Everything else of the
#: package's tree is read whole (``tree_digest``): no list of modules to keep.
ABOVE_THE_BUILD = ("viz", "sweeps.py", "cli.py")


def _tree_files() -> list[tuple[tuple[str, ...], str]]:
    """Every source file of the package that can shape generated code, as ``(its relative
    path's parts, its path)``, in a fixed order (by those parts). Plain strings, not
    ``pathlib``: on a cached build's path, where ``pathlib`` took 3 of the 7 ms."""
    out = []
    skip = {*ABOVE_THE_BUILD, "generated"}
    root = str(PACKAGE_DIR)
    for top, dirs, names in os.walk(root):
        at_root = top == root
        rel = () if at_root else tuple(os.path.relpath(top, root).split(os.sep))
        dirs[:] = [d for d in dirs if d != "__pycache__" and not (at_root and d in skip)]
        for name in names:
            if name.endswith((".py", ".c", ".h")) and not (at_root and name in skip):
                path = os.path.join(top, name)
                if os.path.isfile(path):
                    out.append(((*rel, name), path))
    return sorted(out)


@lru_cache(maxsize=1)
def tree_digest() -> str:
    """Hash of the package's own source tree below its top floors (``ABOVE_THE_BUILD``), read
    whole: every module, C file and header, by relative path and content (3-8 ms, once a
    process).

    Raises
    ------
    SourcesChangedError
        The files' stamp is not the one this process keyed its first build by
        (``sources_stamp``): they changed since, and the code in memory is not theirs."""
    files = _tree_files()
    h = hashlib.sha256()
    for parts, path in files:
        h.update("/".join(parts).encode() + b"\0")
        with open(path, "rb") as f:
            h.update(f.read())
        h.update(b"\0")
    if sources_stamp.cache_info().currsize and _stamp(files) != sources_stamp():
        sources_stamp.cache_clear()  # (a process that goes on builds by what is on disk now)
        raise SourcesChangedError(
            f"the package's source files under {PACKAGE_DIR} changed (an edit, a checkout) since "
            "this process first built from them: the code it runs is not theirs, and a model "
            "built now would be stored under their hash. Restart Python to build with them")
    return h.hexdigest()


def _stamp(files) -> str:
    h = hashlib.sha256(str(PACKAGE_DIR).encode() + b"\0")
    for parts, path in files:
        st = os.stat(path)
        h.update(f"{'/'.join(parts)}:{st.st_size}:{st.st_mtime_ns}:{st.st_ctime_ns}:{st.st_dev}:"
                 f"{st.st_ino}\0".encode())
    return h.hexdigest()


@lru_cache(maxsize=1)
def sources_stamp() -> str:
    """The package's source tree (``tree_digest``'s files, under ``PACKAGE_DIR``) by each
    file's path, size, modification and change times, device and inode, without reading it
    (~0.5 ms, against 3-8 ms read whole), taken once a process, at its first build. A lookup's
    key only (``pipeline.stages.definition_key``): an edited file gets a new stamp, so the
    lookup misses and the build hashes the tree whole; no code is keyed by it. A tree read
    whole later in the process must still have this stamp (``tree_digest``)."""
    return _stamp(_tree_files())


#: The cache root of this context (``root_override``), else None: a context variable, so
#: that one thread's (or one asyncio task's) override never leaks into another's. Threads the
#: package starts for a build run in the context of the thread that starts them
#: (``contextvars.copy_context``, ``toolchain.objects``, ``toolchain.compiler``).
_ROOT_OVERRIDE: ContextVar[Path | None] = ContextVar("grasping_sym_cache_root", default=None)


@contextmanager
def root_override(path: Path):
    """Use ``path`` as the cache root inside the ``with`` block, in this context only
    (``generate_committed`` derives everything afresh in a private root)."""
    token = _ROOT_OVERRIDE.set(Path(path))
    try:
        yield Path(path)
    finally:
        _ROOT_OVERRIDE.reset(token)


def cache_root() -> Path:
    override = _ROOT_OVERRIDE.get()
    if override is not None:
        return override
    env = os.environ.get("GRASPING_SYM_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "grasping_sym"


@lru_cache(maxsize=1)
def casadi_version() -> str:
    """CasADi's version: the imported module's when CasADi is imported, else read from its
    distribution's metadata (the store, and so the runtime, never imports CasADi for it)."""
    loaded = sys.modules.get("casadi")
    version = getattr(loaded, "__version__", None)
    if isinstance(version, str):
        return version
    from importlib import metadata  # noqa: PLC0415 - 13 ms, only when CasADi is not imported
    return metadata.version("casadi")


def content_hash(scene_key: str, version: str, sources: str | None = None) -> dict:
    """The hash of a model's generated code and the inputs it covers (recorded in the
    manifest): the scene's code key, the package's version and source tree
    (``tree_digest``, or ``sources`` where given: a lookup's key, ``sources_stamp``), CasADi's
    version. The compiler and its flags shape the library, not the C: the manifest records
    them beside the library's checksum (``compiled_with``), and a library compiled otherwise is
    compiled again."""
    inputs = {
        "scene": hashlib.sha256(scene_key.encode()).hexdigest(),
        "grasping_sym": version,
        "casadi": casadi_version(),
        "sources": tree_digest() if sources is None else sources,
    }
    h = hashlib.sha256("\n".join(f"{k}={inputs[k]}" for k in sorted(inputs)).encode())
    return {"hash": h.hexdigest(), "inputs": inputs}


def cache_dir(name: str, digest: str) -> Path:
    return cache_root() / f"{name}-{digest[:16]}"


def committed_dir(name: str) -> Path:
    return generated_dir() / name


# ---------------------------------------------------------------------------- entries
# What the package makes at the cache root, and nothing else: ``cache clear`` removes these
# only, and refuses a root that holds anything more (GRASPING_SYM_CACHE pointed at a folder
# of one's own files must never lose them).

#: A built model's directory: ``<scene name>-<hash16>`` (``cache_dir``).
_MODEL_DIR = re.compile(r"(?P<scene>[^/\\]+)-(?P<hash>[0-9a-f]{16})")
#: Shared directories at the root, and the names of what the package keeps in each.
SHARED_DIRS = {
    # codegen.structure_cache: a structure's directory, and the lock of its writing
    "structures": re.compile(r"gs_structure_[0-9a-f]{12}|\.gs_structure_[0-9a-f]{12}\.lock"),
    "templates": re.compile(r"(planar|finger)-[\w.+-]+\.json"),  # codegen.templates
    "objects": re.compile(r"driver-[0-9a-f]{16}"),  # codegen.objects
    "definitions": re.compile(r"[0-9a-f]{32}\.json"),  # pipeline.stages (definition_key)
    "urdf": re.compile(r"[0-9a-f]{32}\.json"),  # model.hands (a URDF file's parsed record)
}
#: The files an unfinished build (no manifest yet) may have left in a model's directory.
_BUILD_FILE = re.compile(r"[\w.+-]+\.(c|h|json|so|o|dylib|lock)")


def _is_model_dir(path: Path) -> bool:
    """A model's directory: its name ``<scene>-<hash16>`` and its manifest naming that scene and
    hash, or (a build stopped before its manifest) only the files a build writes."""
    m = _MODEL_DIR.fullmatch(path.name)
    if m is None:
        return False
    manifest = stored.read_manifest(path) if not os.path.islink(path / stored.MANIFEST) else None
    if manifest is not None:
        return manifest.get("name") == m["scene"] and str(manifest.get("hash", "")).startswith(m["hash"])
    for e in os.scandir(path):
        if safety.is_temporary(e.name):
            continue
        if not (e.is_file(follow_symlinks=False) and _BUILD_FILE.fullmatch(e.name)):
            return False
    return True


def _is_entry(path: Path) -> bool:
    """Whether ``path``, a child of the cache root, is something the package made there: a
    real directory (never a link) that is a model's directory or one of ``SHARED_DIRS``
    holding only what the package keeps there (and a build's temporaries)."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    if not stat.S_ISDIR(st.st_mode):
        return False
    pattern = SHARED_DIRS.get(path.name)
    if pattern is None:
        return _is_model_dir(path)
    return all(safety.is_temporary(e.name) or pattern.fullmatch(e.name) and not e.is_symlink()
               for e in os.scandir(path))


def entries(root: Path | None = None) -> tuple[list[Path], list[Path]]:
    """``(made, foreign)``: the children of the cache root the package made (``_is_entry``),
    and everything else there, sorted by name."""
    root = cache_root() if root is None else Path(root)
    made, foreign = [], []
    for p in sorted(root.iterdir(), key=lambda p: p.name):
        (made if _is_entry(p) else foreign).append(p)
    return made, foreign


def _entry_names(given: Sequence[str]) -> list[str]:
    """The names given to ``clear``, each a plain name of the root's children (no path)."""
    bad = [n for n in given if not n or n in (".", "..") or "/" in n or "\\" in n or "\0" in n
           or os.path.isabs(n)]
    if bad:
        raise CacheContentsError(
            f"{bad}: give entries by their name in the cache root (as `cache list` shows them, "
            "e.g. paper2d-0123456789abcdef) or a scene's name, never a path")
    return list(given)


def select(made: list[Path], names: Sequence[str], root: Path) -> list[Path]:
    """The entries of ``made`` that ``names`` name (a directory's name, or a scene's name for
    all its entries; none: all of them); a name that names no entry is refused."""
    wanted = _entry_names(names)

    def scene(p: Path) -> str | None:
        m = _MODEL_DIR.fullmatch(p.name)
        return m["scene"] if m else None

    unknown = [n for n in wanted if not any(p.name == n or scene(p) == n for p in made)]
    if unknown:
        raise CacheContentsError(f"no cache entries named {unknown} in {root} (see `grasping-sym cache list`)")
    return [p for p in made if not wanted or p.name in wanted or scene(p) in wanted]


def clear(names: Sequence[str] = (), root: Path | None = None) -> list[Path]:
    """Remove the cache entries ``names`` (a directory's name, or a scene's name for all its
    models; default every entry) and return what was removed.

    Raises
    ------
    CacheContentsError
        The root holds anything the package did not make (nothing is removed then: it is not
        a cache of the package's own), or a name is a path or names no entry.
    UnsafeCacheError
        The root or an entry is a link, another user's, or writable by others.
    """
    root = cache_root() if root is None else Path(root)
    wanted = _entry_names(names)
    if not os.path.lexists(root):
        if wanted:
            raise CacheContentsError(f"no cache entries named {wanted}: there is no cache at {root} yet")
        return []
    safety.check_dir(root)
    made, foreign = entries(root)
    if foreign:
        shown = ", ".join(p.name + ("/" if p.is_dir() and not p.is_symlink() else "") for p in foreign[:8])
        more = f" and {len(foreign) - 8} more" if len(foreign) > 8 else ""
        raise CacheContentsError(
            f"refusing to clear the cache root {root}: it holds {len(foreign)} entries grasping_sym "
            f"did not make ({shown}{more}). Nothing was removed. Point GRASPING_SYM_CACHE at a "
            "directory used only by grasping_sym (unset, it is ~/.cache/grasping_sym), or remove "
            "the package's entries by hand")

    chosen = select(made, names, root)
    for p in chosen:
        safety.check_dir(p)
    removed = []
    for p in chosen:
        shutil.rmtree(p)  # removes links inside, never what they point to
        removed.append(p)
    return removed
