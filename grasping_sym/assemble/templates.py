"""Where templates come from: the user cache, the committed ones, or a fresh derivation.

A template depends only on a scene's structure, so it is derived with SymPy once per
structure and stored as serialized CasADi functions under ``<cache root>/templates/`` (and,
for the structures of the built-in scenes and their variants, committed under
``generated/templates/``):

- 2D: the closed loop of a planar structure (``functions.Template``); a new shape is composed
  onto it, with no SymPy derivation on the way to C;
- 3D: each finger chain's kinematics and Lagrangian dynamics (``derive.finger_templates``); a new
  pair of surfaces derives only the surfaces' forms.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import casadi as ca

from grasping_sym.assemble.functions import Template, build_template
from grasping_sym.derive.planar import derive_template
from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.store.templates import cache_dir, committed_templates_dir, load_record

#: The committed planar structures: (one shared contact parameter?, gravity?), one finger.
#: Scenes with several fingers derive their structure once into the user cache.
PLANAR_STRUCTURES = ((True, False), (False, False), (True, True), (False, True))


def template_name(shared: bool, gravity: bool, n_fingers: int = 1, free: bool = False) -> str:
    fingers = "" if n_fingers == 1 else f"-{n_fingers}fingers"
    return (f"planar-{'s' if shared else 'u0u1'}-{'gravity' if gravity else 'horizontal'}{fingers}"
            + ("-free" if free else ""))


def template_key(shared: bool, gravity: bool, n_fingers: int = 1, free: bool = False) -> str:
    """Hash of what a template depends on: the structure, the package's source tree
    (``cache.tree_digest``), CasADi's version."""
    name = template_name(shared, gravity, n_fingers, free)
    text = f"{name}|{cache.tree_digest()}|{ca.__version__}"
    return hashlib.sha256(text.encode()).hexdigest()


def _read(path: Path, key: str, from_cache: bool = True) -> Template | None:
    d = load_record(path, key, from_cache, ("rhs", "outputs"))
    return None if d is None else Template.from_json(d)


def write_template(path: Path, template: Template, key: str) -> None:
    safety.write_text(path, json.dumps({"key": key, **template.to_json()}, sort_keys=True) + "\n")


def derive_and_build(shared: bool, gravity: bool, n_fingers: int = 1,
                     free: bool = False) -> Template:
    return build_template(derive_template(shared, gravity, n_fingers, free))


def planar_template(shared: bool, gravity: bool, n_fingers: int = 1,
                    free: bool = False) -> tuple[Template, str]:
    """The template of a planar structure and where it came from."""
    key = template_key(shared, gravity, n_fingers, free)
    name = f"{template_name(shared, gravity, n_fingers, free)}.json"
    for source, directory in (("cache", cache_dir()), ("committed", committed_templates_dir())):
        found = _read(directory / name, key, from_cache=source == "cache")
        if found is not None:
            return found, source
    template = derive_and_build(shared, gravity, n_fingers, free)
    write_template(cache_dir() / name, template, key)
    return template, "derived"
