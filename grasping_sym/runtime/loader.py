"""Load a built model from its directory: the compiled library, ``manifest.json`` and
``start.json`` (``runtime.stored``). Imports neither SymPy nor the code generation."""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

import numpy as np

from grasping_sym.runtime.model import Model
from grasping_sym.store import files as stored
from grasping_sym.store import safety
from grasping_sym.store.manifest_schema import manifest_problems
from grasping_sym.toolchain.compiler import isa_level, vector_libm


def library_tag() -> str:
    """What ties a compiled library to this interpreter (the fast path is an extension) and
    to the instruction set it was compiled for (``compiler.isa_level``, with ``-mvec`` when
    it calls glibc's vector libm, ``compiler.vector_libm``), and ``$CC`` when set (``-cc``
    and a hash of it: another compiler makes another library)."""
    mvec = "-mvec" if vector_libm() else ""
    cc = os.environ.get("CC", "").strip()
    cc = f"-cc{hashlib.sha256(cc.encode()).hexdigest()[:8]}" if cc else ""
    return f"{sys.implementation.cache_tag}-numpy{np.__version__}-{isa_level()}{mvec}{cc}"


def library_name(name: str) -> str:
    """File name of a model's compiled library for this interpreter and CPU."""
    return f"lib{name}.{library_tag()}.so"


def load(path: Path | str) -> Model:
    """The built model at ``path``: ``model.path`` (its start file, ``<directory>/starts/
    <key>.json``: the same model, start included), or a model's ``directory`` (the start it
    was last built with). Needs no SymPy, no derivation and no compiler: the library must
    have been compiled for this interpreter, NumPy and CPU level (``gs.build`` does that).
    """
    path = Path(path)
    if path.is_file() and path.parent.name == stored.STARTS_DIR:
        directory, start_file = path.parent.parent, path
        safety.check_dir(path.parent)
    else:
        directory, start_file = path, path / stored.START
    if not directory.is_dir():
        raise FileNotFoundError(f"{directory} holds no built model (manifest.json and start.json): "
                                "pass a model's directory (model.path) after gs.build(scene)")
    safety.check_tree(directory, (stored.MANIFEST,))
    if start_file.exists():
        safety.check_file(start_file)
    start, manifest = stored.read_json(start_file), stored.read_manifest(directory)
    for file, data in ((directory / stored.MANIFEST, manifest), (start_file, start)):
        if data is None and file.is_file():
            raise safety.CorruptCacheError(f"{file} is not a JSON object (damaged or edited): rebuild "
                                           "the model with gs.build(scene, force=True)")
    if manifest is None or start is None:
        raise FileNotFoundError(f"{directory} holds no built model (manifest.json and start.json): "
                                "pass a model's directory (model.path) after gs.build(scene)")
    if problems := manifest_problems(manifest):
        raise safety.CorruptCacheError(
            f"{directory / stored.MANIFEST} is not a valid manifest ({'; '.join(problems)}): "
            "rebuild the model with gs.build(scene, force=True)")
    if problems := stored.start_problems(start, manifest):
        raise safety.CorruptCacheError(
            f"{start_file} is not a valid start of {manifest['name']} ({'; '.join(problems)}): "
            "rebuild the model with gs.build(scene, force=True)")
    lib = directory / library_name(manifest["name"])
    if not lib.exists():
        raise FileNotFoundError(f"{lib} is missing: the model was built by another Python, NumPy or "
                                "CPU level; build it here with gs.build(scene)")
    if problem := safety.library_problem(lib, manifest):
        raise safety.CorruptCacheError(f"{problem}: not loaded; rebuild the model with "
                                       "gs.build(scene, force=True)")
    return Model(directory, manifest, lib, start)
