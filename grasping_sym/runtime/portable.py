"""A built model as bytes that another process or machine turns back into the same model:
what ``pickle`` (and so Dask) sends, with no shared filesystem.

The bytes hold the manifest, the start and the model's generated C, and the compiled library
with the tag of the platform it was compiled for (``loader.library_tag``: interpreter, NumPy,
instruction-set level). The receiver looks in its own cache first (the model's directory, by
the manifest's hash); else it installs the library where its platform is the sender's
(checked against the manifest's SHA-256 before it is loaded), or compiles the C there once,
as ``gs.build`` would, and keeps it for later. Either way the receiver's cache holds the model
afterwards and each process loads it once (``restore`` keeps what it made).

A pickle runs what its sender packed, as every pickle does: unpickle models only from
processes you trust (your own Dask workers and client).
"""
from __future__ import annotations

import fcntl
from pathlib import Path

#: Models restored in this process, by (manifest hash, start key).
_RESTORED: dict = {}


def payload(model) -> dict:
    """What ``restore`` needs to make ``model`` again elsewhere."""
    files = {f: (model.directory / f).read_bytes() for f in model.manifest["files"]}
    return {"manifest": model.manifest, "start": model.start, "files": files,
            "library": (model.library_path.name, model.library_path.read_bytes()),
            "structure": _structure_files(model.manifest)}


def _structure_files(manifest: dict) -> dict | None:
    """A model in layers links its structure's objects: the structure's C and record, so that
    a receiver without it can compile them."""
    entry = manifest.get("structure")
    if not entry:
        return None
    from grasping_sym.codegen import structure_cache  # noqa: PLC0415

    meta, directory = structure_cache.locate(entry)
    names = [*meta["files"], structure_cache.META]
    return {"entry": entry, "files": {f: (directory / f).read_bytes() for f in names}}


def restore(data: dict):
    """The model ``data`` (``payload``) describes, from this process's memory, this machine's
    cache, the library bytes, or the C compiled here."""
    key = (data["manifest"]["hash"], data["start"]["key"])
    model = _RESTORED.get(key)
    if model is None:
        model = _RESTORED[key] = _materialise(data)
    return model


def _materialise(data: dict):
    from grasping_sym.codegen import cache  # noqa: PLC0415
    from grasping_sym.runtime import safety, stored  # noqa: PLC0415
    from grasping_sym.runtime.loader import library_name  # noqa: PLC0415
    from grasping_sym.runtime.manifest_schema import manifest_problems  # noqa: PLC0415
    from grasping_sym.runtime.model import Model  # noqa: PLC0415

    manifest, start = data["manifest"], data["start"]
    if problems := manifest_problems(manifest):
        raise safety.CorruptCacheError(f"the model sent has an invalid manifest ({'; '.join(problems)})")
    name = manifest["name"]
    root = cache.cache_root()
    directory = safety.ensure_dir(cache.cache_dir(name, manifest["hash"]), root=root)
    lib = directory / library_name(name)
    with open(safety.write_bytes(directory / ".restore.lock", b""), "rb") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one process per machine compiles, the others wait
        here = stored.read_manifest(directory)
        if here is not None and here.get("hash") == manifest["hash"] and not manifest_problems(here) \
                and safety.library_problem(lib, here) is None:
            manifest = here
        else:
            manifest = _install(directory, lib, manifest, data)
    return Model(directory, manifest, lib, start)


def _install(directory: Path, lib: Path, manifest: dict, data: dict) -> dict:
    """Write the model's files into ``directory`` and its library: the bytes sent where this
    platform is the sender's, else compiled here. Returns the manifest with this library's
    checksum."""
    from grasping_sym.runtime import safety, stored  # noqa: PLC0415

    for f, content in data["files"].items():
        if Path(f).name != f:
            raise safety.CorruptCacheError(f"the model sent names a file {f!r} outside its directory")
        safety.write_bytes(directory / f, content)
    sent_name, sent = data["library"]
    want = manifest.get("libraries", {}).get(sent_name)
    if sent_name == lib.name and want == _sha256(sent):
        safety.write_bytes(lib, sent)
    else:  # another platform (or a library that does not match its manifest): compile here
        if data.get("structure"):
            from grasping_sym.codegen import structure_cache  # noqa: PLC0415

            structure_cache.install_files(data["structure"]["entry"], data["structure"]["files"])
        from grasping_sym.pipeline import compile_library  # noqa: PLC0415

        compile_library(directory, manifest)
        manifest = {**manifest, "libraries": {**manifest.get("libraries", {}),
                                              lib.name: safety.sha256_file(lib)}}
    stored.write_manifest(directory, manifest)
    if safety.library_problem(lib, manifest):
        raise safety.CorruptCacheError(f"{lib}: {safety.library_problem(lib, manifest)}")
    return manifest


def _sha256(data: bytes) -> str:
    import hashlib  # noqa: PLC0415

    return hashlib.sha256(data).hexdigest()


def forget() -> None:
    """Drop the models this process restored (tests)."""
    _RESTORED.clear()


__all__ = ["forget", "payload", "restore"]
