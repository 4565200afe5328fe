"""Where a structure's code lives (2D or 3D): written once, compiled once, linked by every model.

A structure (``assemble.structure``) is kept in ``<cache root>/structures/<name>/``:

- ``<name>_1.c``, ``<name>_2.c`` (and headers): its C, with the 4-lane rhs;
- ``structure.json``: its hash, key and what a model needs to call it (contour slots,
  outputs, constraint names and states, the 4-lane symbol), read and written as a
  :class:`StructureRecord`;
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
from dataclasses import dataclass
from pathlib import Path

import casadi as ca

from grasping_sym import __version__
from grasping_sym.assemble.structure import (
    LAYOUTS,
    Layout,
    Slot,
    StructureFunctions,
    StructureSpec,
    structure_name,
)
from grasping_sym.emit import cwriter, lanes
from grasping_sym.store import files as stored
from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.toolchain import objects
from grasping_sym.toolchain.compiler import COMPILER_FLAGS, compile_shared

__all__ = ["META", "StructureRecord", "derive_afresh", "ensure", "externals", "install_files",
           "library", "link_objects", "structure_name", "write_structure"]

META = "structure.json"
DIR = "structures"


@dataclass(frozen=True)
class StructureRecord:
    """A structure's ``structure.json``: what a model needs to call it and to link it."""

    name: str
    hash: str
    key: str
    #: its C files and headers; those compiled quick (the parts of a split Jacobian)
    files: tuple[str, ...]
    quick_files: tuple[str, ...]
    #: the C name of each function, by kind (``rhs``, ``jac``, ``jac2``, ...)
    functions: dict[str, str]
    #: how its functions take the model's values (``structure.Layout``)
    layout: Layout
    slots: tuple[Slot, ...]
    #: per function kind, per input of the model's values, the entries it reads
    #: (``StructureFunctions.reads``)
    reads: dict[str, dict[str, tuple[int, ...]]]
    n_leaves: int
    output_names: tuple[str, ...]
    constraint_info: dict
    start_names: tuple[str, ...]
    #: the symbol of its 4-lane rhs, if made
    rhs_lanes: str | None
    rewrites: dict
    op_counts: dict[str, int]

    def entry(self) -> dict[str, str]:
        """What a model's manifest names it by: ``{"name", "hash"}`` (:func:`locate`)."""
        return {"name": self.name, "hash": self.hash}

    @classmethod
    def from_json(cls, data: dict) -> StructureRecord:
        """The record of ``structure.json``'s object ``data``.

        Raises
        ------
        safety.CorruptCacheError
            When ``data`` lacks a field or says neither which values its functions read
            (``leaf_entries`` or ``jet_entries``).
        """
        layouts = [LAYOUTS[k] for k in LAYOUTS if k in data]
        missing = [k for k in _FIELDS if k not in data] + ([] if len(layouts) == 1 else
                                                         [" or ".join(LAYOUTS)])
        if missing:
            raise safety.CorruptCacheError(f"structure record {data.get('name')!r} lacks {missing}")
        (layout,) = layouts
        one = layout.single_input
        if one is None:
            slots = tuple(Slot((state,), tuple(entries)) for state, entries in data["slots"])
            reads = {kind: {k: tuple(v) for k, v in by_input.items()}
                     for kind, by_input in data[layout.entries_key].items()}
        else:
            slots = tuple(Slot(tuple(s[:-1]), tuple(range(s[-1]))) for s in data["slots"])
            reads = {kind: {one: tuple(v)} for kind, v in data[layout.entries_key].items()}
        return cls(name=data["name"], hash=data["hash"], key=data["key"], files=tuple(data["files"]),
                   quick_files=tuple(data["quick_files"]), functions=dict(data["functions"]),
                   layout=layout, slots=slots, reads=reads, n_leaves=data["n_leaves"],
                   output_names=tuple(data["output_names"]),
                   constraint_info=data["constraint_info"],
                   start_names=tuple(data["start_names"]), rhs_lanes=data["rhs_lanes"],
                   rewrites=data["rewrites"], op_counts=dict(data["op_counts"]))

    def to_json(self) -> dict:
        """``structure.json``'s object (:meth:`from_json` reads it back)."""
        one = self.layout.single_input
        if one is None:
            slots = [[s.states[0], list(s.entries)] for s in self.slots]
            reads = {kind: {k: list(v) for k, v in by_input.items()}
                     for kind, by_input in self.reads.items()}
        else:
            slots = [[*s.states, len(s.entries)] for s in self.slots]
            reads = {kind: list(by_input[one]) for kind, by_input in self.reads.items()}
        return {
            "name": self.name, "hash": self.hash, "key": self.key, "files": list(self.files),
            "quick_files": list(self.quick_files), "slots": slots, "n_leaves": self.n_leaves,
            "functions": dict(self.functions), "output_names": list(self.output_names),
            "constraint_info": self.constraint_info, "start_names": list(self.start_names),
            "rhs_lanes": self.rhs_lanes, "rewrites": self.rewrites, "op_counts": dict(self.op_counts),
            self.layout.entries_key: reads,
        }


_FIELDS = ("name", "hash", "key", "files", "quick_files", "slots", "n_leaves", "functions",
           "output_names", "constraint_info", "start_names", "rhs_lanes", "rewrites", "op_counts")


def _entries() -> Path:
    """``<cache root>/structures``, created or checked (``runtime.safety``)."""
    root = cache.cache_root()
    return safety.ensure_dir(root / DIR, root=root)


def _depends_on() -> str:
    """What a structure's code depends on besides its spec: the package's source tree
    (``cache.tree_digest``), CasADi's and the package's versions, the flags."""
    return f"{cache.tree_digest()}|{ca.__version__}|{__version__}|{' '.join(COMPILER_FLAGS)}"


def _complete(directory: Path, digest: str, trusted: bool = False) -> StructureRecord | None:
    """The record of the structure in ``directory`` when it is complete (its files are
    there); a cache directory (not ``trusted``, unlike the package's committed code) is
    checked first (``runtime.safety``)."""
    if not trusted:
        if not os.path.lexists(directory):
            return None
        safety.check_tree(directory, [META])
    meta = stored.read_json(directory / META)
    if meta is None or meta.get("hash") != digest:
        return None
    record = StructureRecord.from_json(meta)
    if not all((directory / f).is_file() for f in record.files):
        return None
    if not trusted:
        safety.check_tree(directory, list(record.files))
    return record


def write_structure(sf: StructureFunctions, key: str, directory: Path, digest: str) -> StructureRecord:
    """Write the C of the structure ``sf`` (named ``structure_name(digest)``) and its
    ``structure.json`` into ``directory``; return the latter's record."""
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
    elif sf.jac is None and sf.outputs is not None and sf.constraints is not None and sf.start is not None:
        # no Jacobian (a 3D grasp's): the rhs and the outputs, called at every step and every
        # output time, each in a file of its own; the constraints (a projected step's, a
        # start's) and the start (once per start) in a third, compiled quick
        groups = [[sf.rhs], [sf.outputs], [sf.constraints, sf.start]]
        quick = [f"{name}_3.c"]
    files, grouped = cwriter.write_c(sf, name, directory, digest, __version__, extra_c=lane_c,
                                     groups=groups)
    record = StructureRecord(
        name=name, hash=digest, key=key, files=tuple(files), quick_files=tuple(quick),
        functions=sf.kinds(), layout=sf.layout, slots=sf.slots, reads=sf.reads,
        n_leaves=sf.n_leaves, output_names=tuple(sf.output_names),
        constraint_info=sf.constraint_info, start_names=tuple(sf.start_names),
        rhs_lanes=f"{name}_rhs_lanes" if lane_c else None,
        rewrites={"rhs_lanes": lanes_status, "vecmath_grouped_calls": grouped},
        op_counts={f"{k}_sx_instructions": f.n_instructions() for k, f in sf.by_kind() if f is not None})
    stored.write_json(directory / META, record.to_json())
    return record


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


def ensure(spec: StructureSpec, make: Callable[[str], tuple[StructureFunctions, str]],
           say: Callable[[str], None] = lambda m: None) -> tuple[StructureRecord, Path, str]:
    """The structure of ``spec`` in the cache: ``(its record, its directory, where it came
    from)``; copied from the committed
    structures (except under :func:`derive_afresh`) or written now when the cache lacks it
    (``make(name)`` gives its functions, named ``<name>_*``, and where their derivation came
    from)."""
    extra = _depends_on()
    digest, name = spec.digest(extra), spec.name(extra)
    directory = _entries() / name
    record = _complete(directory, digest)
    if record is not None:
        return record, directory, "cache"
    # one process or thread writes a structure at a time: a concurrent build of the same
    # structure waits and finds it done instead of deriving it again
    with safety.exclusive(_entries() / f".{name}.lock"):
        record = _complete(directory, digest)
        if record is not None:
            return record, directory, "cache"
        return _write(spec, make, say, name, digest, directory)


def _write(spec, make, say, name: str, digest: str, directory: Path) -> tuple[StructureRecord, Path, str]:
    """``ensure``'s structure copied from the committed ones or derived and written now."""
    committed = cache.generated_dir() / DIR / name
    if not _AFRESH.get() and (cm := _complete(committed, digest, trusted=True)) is not None:
        _install(directory, lambda d: [shutil.copyfile(committed / f, d / f)
                                       for f in [*cm.files, META]])
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


def link_objects(record: StructureRecord, directory: Path) -> list[Path]:
    """The structure's object files for this compiler and instruction set (compiled now when
    missing), for linking into a model library."""
    out = safety.ensure_dir(directory / f"obj-{objects.flags_digest()[:12]}", root=directory)
    sources = [directory / f for f in record.files if f.endswith(".c")]
    quick = [directory / f for f in record.quick_files if f in record.files]
    return objects.cached_objects(sources, out, quick=quick)


def library(record: StructureRecord, directory: Path) -> Path:
    """``lib<name>.so`` of the structure (for ``casadi.external``), linked when missing."""
    objs = link_objects(record, directory)
    so = objs[0].parent / f"lib{record.name}.so"
    if os.path.lexists(so):
        safety.check_file(so)
    else:
        compile_shared([], so, objects=objs)
    return so


def externals(record: StructureRecord, so: Path) -> dict[str, ca.Function]:
    """The structure's functions, loaded from its library, by kind."""
    return {k: ca.external(c_name, str(so)) for k, c_name in record.functions.items()}


def locate(entry: dict) -> tuple[StructureRecord, Path]:
    """The cached structure a model's manifest names (``{"name", "hash"}``), copied from the
    committed structures when the cache lacks it.

    Raises
    ------
    FileNotFoundError
        When neither holds it: rebuild the model (``gs.build(scene, force=True)``).
    """
    directory = _entries() / entry["name"]
    record = _complete(directory, entry["hash"])
    if record is not None:
        return record, directory
    committed = cache.generated_dir() / DIR / entry["name"]
    if (cm := _complete(committed, entry["hash"], trusted=True)) is not None:
        _install(directory, lambda d: [shutil.copyfile(committed / f, d / f)
                                       for f in [*cm.files, META]])
        return cm, directory
    raise FileNotFoundError(
        f"the structure {entry['name']} this model links is neither in the cache "
        f"({directory}) nor committed: rebuild the model with gs.build(scene, force=True)")
