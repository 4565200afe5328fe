"""The committed generated code of the built-in scenes (``generated/``): regenerated, or
checked against a fresh generation (``grasping-sym generate``)."""
from __future__ import annotations

import difflib
import shutil
import tempfile
from pathlib import Path

from grasping_sym.assemble import kinds, structure_cache, templates
from grasping_sym.derive import finger_templates
from grasping_sym.model.scenes import BUILTIN
from grasping_sym.pipeline.making import generate, solve_start
from grasping_sym.store import files as stored
from grasping_sym.store import paths as cache


def _text_diff(old: Path, new: Path, label: str) -> str:
    """A unified diff of two text files (empty when byte-identical), at most 60 lines."""

    a = old.read_bytes() if old.exists() else b""
    b = new.read_bytes()
    if a == b:
        return ""
    lines = list(difflib.unified_diff(a.decode(errors="replace").splitlines(),
                                      b.decode(errors="replace").splitlines(),
                                      f"committed/{label}", f"fresh/{label}", lineterm="", n=1))
    more = f"\n... ({len(lines) - 60} more diff lines)" if len(lines) > 60 else ""
    return "\n".join(lines[:60]) + more if lines else f"{label}: bytes differ (line endings?)"


def generate_committed(names=None, *, check: bool = False,
                       root: Path | None = None) -> dict[str, dict[str, str]]:
    """Regenerate ``generated/<name>/`` for built-in scenes (all by default) and
    ``generated/templates/`` for every planar structure.

    The C, header and manifest of a scene are functions of exact inputs and must match byte
    for byte; its ``start.json`` holds solved numbers and must match to
    ``runtime.stored.START_RTOL``. Returns, per scene (and ``"templates"``), each file that
    differs from a fresh generation with a unified diff (or the entries beyond tolerance);
    empty when up to date. With ``check=True`` nothing is written.
    """


    if root is None:
        checkout = cache.source_checkout()
        if checkout is None and not check:
            raise RuntimeError(
                f"generate writes the committed code into a source checkout, and this package is an "
                f"installed copy ({cache.PACKAGE_DIR}): run it in a clone of the repository "
                "(pip install -e .), or pass root= a directory of your own")
        root = checkout / "generated" if checkout is not None else cache.generated_dir()
    root = Path(root)
    differ: dict[str, dict[str, str]] = {"templates": {}}
    def template(file_name: str, write) -> None:
        """Write a template with ``write(path)``; note and (unless ``check``) replace the
        committed one when it differs."""
        with tempfile.TemporaryDirectory() as tmp:
            fresh = Path(tmp) / file_name
            write(fresh)
            target = root / "templates" / file_name
            if not target.exists() or target.read_bytes() != fresh.read_bytes():
                differ["templates"][file_name] = f"{file_name}: differs (serialized CasADi functions)"
                if not check:
                    target.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(fresh, target)

    for shared, gravity in templates.PLANAR_STRUCTURES:
        template(f"{templates.template_name(shared, gravity)}.json",
                 lambda path, s=shared, g=gravity: templates.write_template(
                     path, templates.derive_and_build(s, g), templates.template_key(s, g)))
    finger_files: set[str] = set()
    differ["structures"] = {}
    structures: set[str] = set()
    with tempfile.TemporaryDirectory() as private, cache.root_override(Path(private)), \
            structure_cache.derive_afresh():
        for name in names or sorted(BUILTIN):
            _generate_scene(BUILTIN[name](), root, check, differ, structures, finger_files, template)
    if set(names or BUILTIN) == set(BUILTIN):  # structures no built-in scene uses are stale
        for old in sorted((root / structure_cache.DIR).glob("*/")):
            if old.name not in structures:
                differ["structures"][old.name] = f"{old.name}: no longer used by a built-in scene"
                if not check:
                    shutil.rmtree(old)
    if set(names or BUILTIN) == set(BUILTIN):  # finger templates no built-in scene uses are stale
        for old in sorted((root / "templates").glob("finger-*.json")):
            if old.name not in finger_files:
                differ["templates"][old.name] = f"{old.name}: no longer used by a built-in scene"
                if not check:
                    old.unlink()
    return differ


def _generate_scene(scene, root: Path, check: bool, differ: dict, structures: set,
                    finger_files: set, template) -> None:
    """``generate_committed`` for one built-in scene: its finger templates, its C and
    manifest, its start and (for a model in layers) its structure."""


    name = scene.name

    for file_name, key, build in kinds.kind(scene).templates(scene):
        finger_files.add(file_name)
        template(file_name, lambda path, b=build, k=key: finger_templates.write_finger_template(path, b(), k))
    target = root / name
    with tempfile.TemporaryDirectory() as tmp:
        fresh = Path(tmp)
        manifest = generate(scene, fresh, count_ops=True)
        record = solve_start(scene)
        stored.write_json(fresh / stored.START, record)
        files = [*manifest["files"], stored.MANIFEST]
        differ[name] = {f: d for f in files if (d := _text_diff(target / f, fresh / f, f"{name}/{f}"))}
        stale = sorted(f.name for f in target.glob("*.[ch]") if f.name not in files)
        differ[name].update({f: f"{name}/{f}: no longer generated" for f in stale})
        old = stored.read_json(target / stored.START)
        if old is None or old.get("key") != record["key"]:
            differ[name][stored.START] = "start.json: missing, or solved for another scene definition"
        elif bad := stored.starts_agree(old, record):
            differ[name][stored.START] = (f"start.json: {len(bad)} entries differ beyond "
                                          f"rtol {stored.START_RTOL:g}: " + "; ".join(bad[:5]))
        if not check:
            target.mkdir(parents=True, exist_ok=True)
            for f in files:
                shutil.copyfile(fresh / f, target / f)
            for f in stale:
                (target / f).unlink()
            if stored.START in differ[name]:  # keep the committed start when it agrees
                shutil.copyfile(fresh / stored.START, target / stored.START)
    if "structure" in manifest:
        entry = manifest["structure"]
        structures.add(entry["name"])
        meta, sdir = structure_cache.locate(entry)
        target = root / structure_cache.DIR / entry["name"]
        files = [*meta.files, structure_cache.META]
        for f in files:
            if d := _text_diff(target / f, sdir / f, f"structures/{entry['name']}/{f}"):
                differ["structures"][f"{entry['name']}/{f}"] = d
                if not check:
                    target.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(sdir / f, target / f)
