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


#: Unknown or repeated output names listed in a message before "... and N more".
LISTED_NAMES = 10


def _listed(names: list) -> str:
    shown = ", ".join(repr(n) for n in names[:LISTED_NAMES])
    more = len(names) - LISTED_NAMES
    return shown + (f", ... and {more} more" if more > 0 else "")


def names_tuple(values):
    """``values`` as a tuple when it is a collection of names; a string or anything else is
    kept as it is, for ``output_problems`` to refuse by name."""
    if isinstance(values, (str, bytes)):
        return values
    try:
        return tuple(values)
    except TypeError:
        return values


def output_problems(outputs: object, known: tuple[str, ...]) -> list[str]:
    """Every reason ``outputs`` cannot be a scene's output selection from ``known`` (empty when
    it can): a tuple of distinct names of ``known``, so at most ``len(known)`` of them. The
    problems are bounded in size whatever was given: at most ``LISTED_NAMES`` names each."""
    if isinstance(outputs, (str, bytes)):
        return [f"outputs = {outputs[:80]!r} is a string: give a tuple of output names, e.g. "
                f"({outputs[:80]!r},)"]
    if not isinstance(outputs, tuple):
        return [f"outputs is {type(outputs).__name__}: give a tuple of output names, e.g. "
                f"{tuple(known[:2])}"]
    n = len(outputs)
    if n > len(known):
        return [f"outputs lists {n} names, but the scene has only {len(known)} distinct "
                f"outputs: name each at most once, from {list(known)}"]
    problems = []
    bad = [k for k in outputs if not isinstance(k, str)]
    if bad:
        problems.append(f"outputs holds {len(bad)} entries that are not names ({_listed(bad)}): "
                        "give each output by its name, a string")
    names = [k for k in outputs if isinstance(k, str)]
    unknown = [k for k in names if k not in known]
    if unknown:
        problems.append(f"unknown output{'s' if len(unknown) > 1 else ''} {_listed(unknown)}: "
                        f"choose from {list(known)}")
    seen: set[str] = set()
    repeated = [k for k in names if k in seen or seen.add(k)]
    if repeated:
        problems.append(f"outputs names {_listed(sorted(set(repeated)))} more than once: name each "
                        "output once (a result holds one column per name)")
    return problems
