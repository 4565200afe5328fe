"""Where a planar structure's code lives: written once, compiled once, linked by every model.

A structure (``codegen.structure``) is kept in ``<cache root>/structures/<name>/``:

- ``<name>_1.c``, ``<name>_2.c`` (and headers): its C, with the 4-lane rhs;
- ``structure.json``: its hash, key and what a model needs to call it (contour slots,
  outputs, constraint names and states, the 4-lane symbol);
- ``obj-<flags>/``: its object files for one compiler and instruction set, which model
  libraries link, and ``lib<name>.so`` built from them, which ``casadi.external`` loads while
  a model is composed.

``<name>`` is ``gs_structure_<hash12>``: the hash covers the structure's key, the package's
sources and CasADi's version, so a symbol name never means two codes. The structures of the
built-in scenes are committed under ``generated/structures/`` and copied from there.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

import casadi as ca

from grasping_sym import __version__
from grasping_sym.assemble.structure import StructureFunctions
from grasping_sym.emit import cwriter, lanes
from grasping_sym.store import files as stored
from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.toolchain import objects
from grasping_sym.toolchain.compiler import COMPILER_FLAGS, compile_shared

__all__ = ["META", "derive_afresh", "ensure", "externals", "install_files", "library", "link_objects",
           "structure_name", "write_structure"]

META = "structure.json"
DIR = "structures"


def _entries() -> Path:
    """``<cache root>/structures``, created or checked (``runtime.safety``)."""
    root = cache.cache_root()
    return safety.ensure_dir(root / DIR, root=root)


def structure_hash(spec) -> str:
    """The hash of a structure: its key, the package's source tree (``cache.tree_digest``),
    CasADi's and the package's versions, the flags."""
    return spec.digest(f"{cache.tree_digest()}|{ca.__version__}|{__version__}|"
                       f"{' '.join(COMPILER_FLAGS)}")


def structure_name(digest: str) -> str:
    return f"gs_structure_{digest[:12]}"


def _complete(directory: Path, digest: str, trusted: bool = False) -> dict | None:
    """``structure.json`` of the structure in ``directory`` when it is complete (its files
    are there); a cache directory (not ``trusted``, unlike the package's committed code) is
    checked first (``runtime.safety``)."""
    if not trusted:
        if not os.path.lexists(directory):
            return None
        safety.check_tree(directory, [META])
    meta = stored.read_json(directory / META)
    if meta is None or meta.get("hash") != digest:
        return None
    if not all((directory / f).is_file() for f in meta["files"]):
        return None
    if not trusted:
        safety.check_tree(directory, meta["files"])
    return meta


def write_structure(sf: StructureFunctions, key: str, directory: Path, digest: str) -> dict:
    """Write the C of the structure ``sf`` (named ``structure_name(digest)``) and its
    ``structure.json`` into ``directory``; return the latter."""
    name = sf.name
    lane_c, lanes_status = None, "not made: the structure's rhs has no lane layout"
    if sf.lanes is not None:
        lane_c, lanes_status = lanes.function_lanes(sf.rhs, f"{name}_rhs_lanes", *sf.lanes)
    groups, quick = None, []
    if sf.jac2 is not None:
        # a split Jacobian: each part in a file of its own, compiled quick, with the functions
        # called once per output time or start (the outputs with one part, the start with
        # the other)
        with_jac = [f for f in (sf.jac, sf.outputs) if f is not None]
        with_jac2 = [f for f in (sf.jac2, sf.start) if f is not None]
        apart = {id(f) for f in with_jac + with_jac2}
        groups = [[f for f in sf.functions() if id(f) not in apart], with_jac, with_jac2]
        quick = [f"{name}_{k}.c" for k in (2, 3)]
    files, grouped = cwriter.write_c(sf, name, directory, digest, __version__, extra_c=lane_c,
                                     groups=groups)
    meta = {
        "name": name, "hash": digest, "key": key, "files": files, "quick_files": quick,
        "slots": [list(map(lambda v: list(v) if isinstance(v, tuple) else v, s)) for s in sf.slots],
        "n_leaves": sf.n_leaves, "functions": sf.kinds(),
        "output_names": list(sf.output_names), "constraint_info": sf.constraint_info,
        "start_names": list(sf.start_names),
        "rhs_lanes": f"{name}_rhs_lanes" if lane_c else None,
        "rewrites": {"rhs_lanes": lanes_status, "vecmath_grouped_calls": grouped},
        "op_counts": {f"{k}_sx_instructions": f.n_instructions()
                      for k, f in sf.by_kind() if f is not None},
        **(sf.extra_meta or {}),
    }
    stored.write_json(directory / META, meta)
    return meta


#: True inside ``derive_afresh`` in this context (a context variable: another thread's build
#: still copies the committed structures).
_AFRESH: ContextVar[bool] = ContextVar("grasping_sym_derive_afresh", default=False)


@contextmanager
def derive_afresh():
    """Inside the ``with`` block, in this context, structures are never copied from the
    committed ones (``generate_committed`` checks them against a fresh derivation)."""
    token = _AFRESH.set(True)
    try:
        yield
    finally:
        _AFRESH.reset(token)


def ensure(spec, make: Callable[[str], tuple[StructureFunctions, str]],
           say: Callable[[str], None] = lambda m: None) -> tuple[dict, Path, str]:
    """The structure of ``spec`` (anything with ``key()`` and ``digest(extra)``) in the cache:
    ``(structure.json, its directory, where it came from)``; copied from the committed
    structures (except under :func:`derive_afresh`) or written now when the cache lacks it
    (``make(name)`` gives its functions, named ``<name>_*``, and where their derivation came
    from)."""
    digest = structure_hash(spec)
    name = structure_name(digest)
    directory = _entries() / name
    meta = _complete(directory, digest)
    if meta is not None:
        return meta, directory, "cache"
    committed = cache.generated_dir() / DIR / name
    if not _AFRESH.get() and (cm := _complete(committed, digest, trusted=True)) is not None:
        _install(directory, lambda d: [shutil.copyfile(committed / f, d / f)
                                       for f in [*cm["files"], META]])
        return cm, directory, "committed"
    sf, source = make(name)
    say(f"writing the C of structure {name} ({source})")
    _install(directory, lambda d: write_structure(sf, spec.key(), d, digest))
    return _complete(directory, digest), directory, f"derived ({source})"


def _install(directory: Path, fill) -> None:
    """Fill a fresh directory with ``fill(path)`` and move its files into ``directory``
    (each replaced atomically; concurrent builds write the same bytes)."""
    safety.ensure_dir(directory, root=cache.cache_root())
    with tempfile.TemporaryDirectory(dir=directory, prefix=".write-") as tmp:
        fill(Path(tmp))
        names = sorted(p.name for p in Path(tmp).iterdir())
        for n in sorted(names, key=lambda n: n == META):  # the record last: it marks complete
            os.replace(Path(tmp) / n, directory / n)


def install_files(entry: dict, files: dict[str, bytes]) -> None:
    """A structure's files as another machine sent them (``runtime.portable``), into this
    machine's cache when it lacks the structure ``entry`` names."""
    try:
        locate(entry)
        return
    except FileNotFoundError:
        pass
    if any(Path(f).name != f for f in files):
        raise safety.CorruptCacheError(f"the structure sent names files outside its directory: {sorted(files)}")
    _install(_entries() / entry["name"],
             lambda d: [(d / f).write_bytes(content) for f, content in files.items()])


def link_objects(meta: dict, directory: Path) -> list[Path]:
    """The structure's object files for this compiler and instruction set (compiled now when
    missing), for linking into a model library."""
    out = safety.ensure_dir(directory / f"obj-{objects.flags_digest()[:12]}", root=directory)
    sources = [directory / f for f in meta["files"] if f.endswith(".c")]
    quick = [directory / f for f in meta.get("quick_files", []) if f in meta["files"]]
    return objects.cached_objects(sources, out, quick=quick)


def library(meta: dict, directory: Path) -> Path:
    """``lib<name>.so`` of the structure (for ``casadi.external``), linked when missing."""
    objs = link_objects(meta, directory)
    so = objs[0].parent / f"lib{meta['name']}.so"
    if os.path.lexists(so):
        safety.check_file(so)
    else:
        compile_shared([], so, objects=objs)
    return so


def externals(meta: dict, so: Path) -> dict[str, ca.Function]:
    """The structure's functions, loaded from its library."""
    return {k: ca.external(c_name, str(so)) for k, c_name in meta["functions"].items()}


def locate(entry: dict) -> tuple[dict, Path]:
    """The cached structure a model's manifest names (``{"name", "hash"}``), copied from the
    committed structures when the cache lacks it.

    Raises
    ------
    FileNotFoundError
        When neither holds it: rebuild the model (``gs.build(scene, force=True)``).
    """
    directory = _entries() / entry["name"]
    meta = _complete(directory, entry["hash"])
    if meta is not None:
        return meta, directory
    committed = cache.generated_dir() / DIR / entry["name"]
    if (cm := _complete(committed, entry["hash"], trusted=True)) is not None:
        _install(directory, lambda d: [shutil.copyfile(committed / f, d / f)
                                       for f in [*cm["files"], META]])
        return cm, directory
    raise FileNotFoundError(
        f"the structure {entry['name']} this model links is neither in the cache "
        f"({directory}) nor committed: rebuild the model with gs.build(scene, force=True)")
