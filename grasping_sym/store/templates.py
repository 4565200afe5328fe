"""Where derived templates are stored and how a stored one is read: the user cache's
``templates/`` and the committed ``generated/templates/``, each record checked to hold plain
SX only before CasADi deserializes it (the planar templates, ``assemble.templates``; the
finger templates, ``derive.finger_templates``)."""
from __future__ import annotations

import json
import os
from pathlib import Path

from grasping_sym.errors import UnsafeTemplateError
from grasping_sym.store import paths as cache
from grasping_sym.store import safety


def committed_templates_dir() -> Path:
    return cache.generated_dir() / "templates"


#: Class names in a serialized CasADi function that load code when it is deserialized (a
#: compiled library, a just-in-time compiler, an importer plugin): never read from a file.
_LOADS_CODE = (b"External", b"DllLibrary", b"JitLibrary", b"Importer", b"Jit")


def plain_sx(serialized: str, path: Path) -> str:
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


def load_record(path: Path, key: str, from_cache: bool, fields: tuple[str, ...]) -> dict | None:
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
        plain_sx(d.get(f), path)
    return d


def cache_dir() -> Path:
    root = cache.cache_root()
    return safety.ensure_dir(root / "templates", root=root)
