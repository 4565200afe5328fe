"""Where templates come from: the user cache, the committed ones, or a fresh derivation.

A template depends only on a scene's structure, so it is derived with SymPy once per
structure and stored as serialized CasADi functions under ``<cache root>/templates/`` (and,
for the structures of the built-in scenes and their variants, committed under
``generated/templates/``):

- 2D: the closed loop of a planar structure (``functions.Template``); a new shape is composed
  onto it, with no SymPy derivation on the way to C;
- 3D: each finger chain's kinematics and Lagrangian dynamics (``finger_template``); a new
  pair of surfaces derives only the surfaces' forms.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import casadi as ca

from grasping_sym.assemble.functions import Template, build_template
from grasping_sym.derive.planar import derive_template
from grasping_sym.errors import UnsafeTemplateError
from grasping_sym.store import paths as cache
from grasping_sym.store import safety

#: The committed planar structures: (one shared contact parameter?, gravity?), one finger.
#: Scenes with several fingers derive their structure once into the user cache.
PLANAR_STRUCTURES = ((True, False), (False, False), (True, True), (False, True))


def template_name(shared: bool, gravity: bool, n_fingers: int = 1) -> str:
    fingers = "" if n_fingers == 1 else f"-{n_fingers}fingers"
    return f"planar-{'s' if shared else 'u0u1'}-{'gravity' if gravity else 'horizontal'}{fingers}"


def template_key(shared: bool, gravity: bool, n_fingers: int = 1) -> str:
    """Hash of what a template depends on: the structure, the package's source tree
    (``cache.tree_digest``), CasADi's version."""
    text = f"{template_name(shared, gravity, n_fingers)}|{cache.tree_digest()}|{ca.__version__}"
    return hashlib.sha256(text.encode()).hexdigest()


def committed_templates_dir() -> Path:
    return cache.generated_dir() / "templates"


#: Class names in a serialized CasADi function that load code when it is deserialized (a
#: compiled library, a just-in-time compiler, an importer plugin): never read from a file.
_LOADS_CODE = (b"External", b"DllLibrary", b"JitLibrary", b"Importer", b"Jit")


def _plain_sx(serialized: str, path: Path) -> str:
    """``serialized`` (CasADi's text serialization: one byte per two letters ``a``-``p``, low
    nibble first) when it holds plain SX functions only; else raise
    :class:`UnsafeTemplateError`. Checked before ``casadi.Function.deserialize``, which would
    dlopen the library a serialized ``External`` names."""
    if not isinstance(serialized, str) or len(serialized) % 2 or not set(serialized) <= set("abcdefghijklmnop"):
        raise UnsafeTemplateError(f"{path}: not a CasADi serialization; delete the file")
    raw = bytes(((ord(serialized[i + 1]) - 97) << 4) | (ord(serialized[i]) - 97)
                for i in range(0, len(serialized), 2))
    bad = [c.decode() for c in _LOADS_CODE if c in raw]
    if bad or b"SXFunction" not in raw or b"MXFunction" in raw:
        raise UnsafeTemplateError(
            f"{path}: a template must be plain SX functions, and this one holds "
            f"{', '.join(bad) or 'other function classes'}, which would load code when read: "
            "not loaded; delete the file (it will be derived again)")
    return serialized


def _load(path: Path, key: str, from_cache: bool, fields: tuple[str, ...]) -> dict | None:
    """The template record at ``path`` when its key is ``key``; a cache file is checked first
    (``runtime.safety``: yours alone) and every serialized field must be plain SX."""
    if from_cache:
        if not os.path.lexists(path):
            return None
        safety.check_file(path)
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(d, dict) or d.get("key") != key:
        return None
    for f in fields:
        _plain_sx(d.get(f), path)
    return d


def _cache_dir() -> Path:
    root = cache.cache_root()
    return safety.ensure_dir(root / "templates", root=root)


def _read(path: Path, key: str, from_cache: bool = True) -> Template | None:
    d = _load(path, key, from_cache, ("rhs", "outputs"))
    return None if d is None else Template.from_json(d)


def write_template(path: Path, template: Template, key: str) -> None:
    safety.write_text(path, json.dumps({"key": key, **template.to_json()}, sort_keys=True) + "\n")


def derive_and_build(shared: bool, gravity: bool, n_fingers: int = 1) -> Template:
    return build_template(derive_template(shared, gravity, n_fingers))


def finger_template_key(chain, gravity) -> str:
    """Hash of what a finger template depends on: the chain, gravity, the package's source
    tree (``cache.tree_digest``), CasADi."""
    text = f"finger|{chain!r}|{gravity!r}|{cache.tree_digest()}|{ca.__version__}"
    return hashlib.sha256(text.encode()).hexdigest()


def finger_template_name(chain, gravity) -> str:
    return f"finger-{chain.name}-{'gravity' if gravity else 'horizontal'}-" \
           f"{finger_template_key(chain, gravity)[:12]}.json"


def finger_template(chain, gravity, build) -> tuple[ca.Function, str]:
    """The finger template ``(q, dq) -> pieces`` of ``chain`` under ``gravity`` and where it
    came from (``"cache"``, ``"committed"`` or ``"derived"``: then ``build()`` made it and it
    is stored in the cache)."""
    key = finger_template_key(chain, gravity)
    name = finger_template_name(chain, gravity)
    for source, directory in (("cache", _cache_dir()), ("committed", committed_templates_dir())):
        d = _load(directory / name, key, source == "cache", ("function",))
        if d is not None:
            return ca.Function.deserialize(d["function"]), source
    fn = build()
    write_finger_template(_cache_dir() / name, fn, key)
    return fn, "derived"


def write_finger_template(path: Path, fn: ca.Function, key: str) -> None:
    safety.write_text(path, json.dumps({"key": key, "function": fn.serialize()}, sort_keys=True) + "\n")


def planar_template(shared: bool, gravity: bool, n_fingers: int = 1) -> tuple[Template, str]:
    """The template of a planar structure and where it came from."""
    key = template_key(shared, gravity, n_fingers)
    name = f"{template_name(shared, gravity, n_fingers)}.json"
    for source, directory in (("cache", _cache_dir()), ("committed", committed_templates_dir())):
        found = _read(directory / name, key, from_cache=source == "cache")
        if found is not None:
            return found, source
    template = derive_and_build(shared, gravity, n_fingers)
    write_template(_cache_dir() / name, template, key)
    return template, "derived"
