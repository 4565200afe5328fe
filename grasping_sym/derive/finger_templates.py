"""The finger templates of the 3D model: a chain's kinematics and dynamics ``(q, dq) ->
pieces``, derived with SymPy once per chain and gravity (``derive.bodies3d.finger_function``)
and stored (``store.templates``): the user cache, the committed ones, or a fresh derivation."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import casadi as ca

from grasping_sym.store import paths as cache
from grasping_sym.store import safety
from grasping_sym.store.templates import cache_dir, committed_templates_dir, load_record


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
    for source, directory in (("cache", cache_dir()), ("committed", committed_templates_dir())):
        d = load_record(directory / name, key, source == "cache", ("function",))
        if d is not None:
            return ca.Function.deserialize(d["function"]), source
    fn = build()
    write_finger_template(cache_dir() / name, fn, key)
    return fn, "derived"


def write_finger_template(path: Path, fn: ca.Function, key: str) -> None:
    safety.write_text(path, json.dumps({"key": key, "function": fn.serialize()}, sort_keys=True) + "\n")
