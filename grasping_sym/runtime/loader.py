"""Load a built model from its directory: the compiled library, ``manifest.json`` and
``start.json`` (``runtime.stored``). Imports neither SymPy nor the code generation."""
from __future__ import annotations

from pathlib import Path

from grasping_sym.runtime.model import Model
from grasping_sym.store import files as stored
from grasping_sym.store import safety
from grasping_sym.store.manifest_schema import manifest_problems
from grasping_sym.store.platform import library_name


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
        raise FileNotFoundError(f"{lib} is missing: the model was built by another Python, NumPy, "
                                "CPU level or GRASPING_SYM_OPT; build it here with gs.build(scene)")
    if problem := safety.library_problem(lib, manifest):
        raise safety.CorruptCacheError(f"{problem}: not loaded; rebuild the model with "
                                       "gs.build(scene, force=True)")
    return Model(directory, manifest, lib, start)
