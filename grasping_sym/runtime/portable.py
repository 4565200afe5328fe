"""A built model as bytes that another process or machine turns back into the same model:
what ``pickle`` (and so Dask) sends, with no shared filesystem.

The bytes hold the manifest, the start and the model's generated C, and the compiled library
with the tag of the platform it was compiled for (``store.platform.library_tag``: interpreter, NumPy,
instruction-set level). The receiver looks in its own cache first (the model's directory, by
the manifest's hash); else it installs the library where its platform is the sender's
(checked against the manifest's SHA-256 before it is loaded). This module never compiles: a
receiver on another platform needs ``compile`` (a model from ``gs.build`` is pickled with the
build's, ``pipeline.built``, which compiles the C there once as ``gs.build`` would); without
it the receiver refuses by name. Either way the receiver's cache holds the model afterwards
and each process loads it once (``restore`` keeps what it made).

A pickle runs what its sender packed, as every pickle does: unpickle models only from
processes you trust (your own Dask workers and client).
"""
from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path

from grasping_sym.errors import CorruptCacheError
from grasping_sym.store import files as stored
from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.store.manifest_schema import manifest_problems
from grasping_sym.store.platform import library_name

#: ``compile(directory, manifest, data)``: the model's library compiled from its C in
#: ``directory`` (the build's, ``pipeline.built``), returning the manifest with the new
#: library's record; None: this process cannot compile.
Compile = Callable[[Path, dict, dict], dict]

#: Models restored in this process, by (manifest hash, start key, the class made).
_RESTORED: dict = {}


def payload(model, **extra) -> dict:
    """What ``restore`` needs to make ``model`` again elsewhere (``extra``: what a builder
    adds, e.g. a layered model's structure files)."""
    files = {f: (model.directory / f).read_bytes() for f in model.manifest["files"]}
    return {"manifest": model.manifest, "start": model.start, "files": files,
            "library": (model.library_path.name, model.library_path.read_bytes()), **extra}


def restore(data: dict, compile: Compile | None, make: Callable):
    """The model ``data`` (``payload``) describes, from this process's memory, this machine's
    cache, the library bytes, or (with ``compile``) the C compiled here. ``make(directory,
    manifest, library, start)`` makes the model object (the pickled model's class)."""
    key = (data["manifest"]["hash"], data["start"]["key"], make)
    model = _RESTORED.get(key)
    if model is None:
        model = _RESTORED[key] = _materialise(data, compile, make)
    return model


def _materialise(data: dict, compile: Compile | None, make):
    manifest, start = data["manifest"], data["start"]
    if problems := manifest_problems(manifest):
        raise CorruptCacheError(f"the model sent has an invalid manifest ({'; '.join(problems)})")
    name = manifest["name"]
    root = cache.cache_root()
    directory = safety.ensure_dir(cache.cache_dir(name, manifest["hash"]), root=root)
    lib = directory / library_name(name)
    with safety.exclusive(directory / ".restore.lock"):  # one process compiles, the others wait
        here = stored.read_manifest(directory)
        if here is not None and here.get("hash") == manifest["hash"] and not manifest_problems(here) \
                and safety.library_problem(lib, here) is None:
            manifest = here
        else:
            manifest = _install(directory, lib, manifest, data, compile)
    return make(directory, manifest, lib, start)


def _install(directory: Path, lib: Path, manifest: dict, data: dict, compile: Compile | None) -> dict:
    """Write the model's files into ``directory`` and its library: the bytes sent where this
    platform is the sender's, else compiled here. Returns the manifest with this library's
    checksum."""
    for f, content in data["files"].items():
        if Path(f).name != f:
            raise CorruptCacheError(f"the model sent names a file {f!r} outside its directory")
        safety.write_bytes(directory / f, content)
    sent_name, sent = data["library"]
    want = manifest.get("libraries", {}).get(sent_name)
    if sent_name == lib.name and want == _sha256(sent):
        safety.write_bytes(lib, sent)
    elif compile is None:
        raise CorruptCacheError(
            f"the model {manifest['name']!r} was sent with a library for another platform "
            f"({sent_name}, this one loads {lib.name}) and this process was given no compiler: "
            "pickle the model made by gs.build (it compiles its C on arrival), or build the "
            "scene on this machine")
    else:  # another platform (or a library that does not match its manifest): compile here
        manifest = compile(directory, manifest, data)
    stored.write_manifest(directory, manifest)
    if safety.library_problem(lib, manifest):
        raise CorruptCacheError(f"{lib}: {safety.library_problem(lib, manifest)}")
    return manifest


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def forget() -> None:
    """Drop the models this process restored (tests)."""
    _RESTORED.clear()


__all__ = ["forget", "payload", "restore"]
