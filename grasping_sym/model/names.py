"""Which scene names are allowed: one rule for 2D and 3D scenes alike.

A scene's name prefixes its C symbols (``{name}_rhs``, ``jac_{name}_rhs``) and names its
files and its cache directory (``{name}-{hash}``), so it must be a C identifier that CasADi,
gcc and the file system all accept unchanged: ASCII letters and digits in words joined by
single underscores, starting with a letter (``paper2d``, ``ellipse_v2``). Refused, because
they pass a plain ``str.isidentifier`` and then fail later: a leading or trailing underscore
or ``__`` (reserved in C, and CasADi builds names of its own with them), non-ASCII letters
(``café``), C keywords, and the prefixes the package's own C symbols use (``gs``, ``casadi``).
"""
from __future__ import annotations

import re

#: ASCII words of letters and digits joined by single underscores, starting with a letter.
NAME_PATTERN = re.compile(r"[A-Za-z][A-Za-z0-9]*(?:_[A-Za-z0-9]+)*\Z", re.ASCII)
#: Longest name: the cache directory adds 17 characters and the library file about 60.
MAX_NAME_LENGTH = 64
#: Prefixes of the package's own C symbols (``gs_radau5``, ``casadi_*``).
RESERVED_PREFIXES = ("gs", "casadi")
C_KEYWORDS = frozenset("""
    auto break case char const continue default do double else enum extern float for goto if
    inline int long register restrict return short signed sizeof static struct switch typedef
    union unsigned void volatile while main""".split())


def name_problems(name: object) -> list[str]:
    """Every reason ``name`` cannot name a scene (empty when it can)."""
    fix = "use ASCII letters and digits in words joined by single underscores, e.g. 'my_scene2'"
    if not isinstance(name, str):
        return [f"name {name!r} is {type(name).__name__}: give a string ({fix})"]
    problems = []
    if not NAME_PATTERN.match(name):
        problems.append(f"name {name!r} is not a safe C identifier and file name: {fix} "
                        "(no leading, trailing or double underscore, no other characters)")
    if len(name) > MAX_NAME_LENGTH:
        problems.append(f"name {name!r} has {len(name)} characters: at most {MAX_NAME_LENGTH}")
    low = name.lower()
    if low in C_KEYWORDS:
        problems.append(f"name {name!r} is a C keyword: choose another")
    for prefix in RESERVED_PREFIXES:
        if low == prefix or low.startswith(prefix + "_"):
            problems.append(f"name {name!r} uses the prefix {prefix!r} of the package's own C "
                            "symbols: choose another")
    return problems
