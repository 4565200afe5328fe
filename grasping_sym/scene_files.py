"""Scenes from TOML files: a built-in scene with its keywords changed, or a 2D finger on shapes
from the library, with numbers written as formulas that are parsed, never run.

```toml
[scene]
base = "planar_finger"          # or a built-in: paper2d, paper3d, pivot3d
name = "my_ellipse"
q1_0 = "pi / 6"                 # any keyword of the base; text is a formula (numbers, pi, E,
u1_0 = "pi + 0.3"               # + - * / **, sqrt, sin, cos, ...)
runtime = ["fd"]

[fingertip]                     # planar_finger: the contours, by library function
shape = "paper_fingertip"       # gs.curves.<shape>(...)

[object]
shape = "ellipse"
a = 0.020
b = 0.015
start = "pi"
span = "pi"
clockwise = true
```

``load_scene(path)`` returns the scene; ``grasping-sym simulate scene.toml --out DIR`` runs it.
Only names the package lists can be called: the built-in scenes, ``gs.curves``' functions
(``geometry.library.__all__``) and, for the 3D scenes' ``object_surface`` / ``tip`` tables,
``geometry.surface_library``'s. Every problem is named at once.
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

from grasping_sym.errors import ProblemsError


class SceneFileError(ProblemsError):
    """A scene file that cannot be read: every problem, with the file."""

    def __init__(self, path, problems: list[str]):
        self.path = path
        super().__init__(f"scene file {path}", problems)


#: The bases a file may name.
BASES = ("planar_finger", "paper2d", "paper3d", "pivot3d")
#: Surface tables of a 3D file: the base's keyword each one sets.
SURFACES_3D = ("object_surface",)


def load_scene(path: str | Path):
    """The scene the TOML file at ``path`` describes (module docstring)."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise SceneFileError(path, [f"not valid TOML: {exc}"]) from None
    except OSError as exc:
        raise SceneFileError(path, [f"cannot read it: {exc.strerror}"]) from None
    problems: list[str] = []
    scene_table = data.get("scene")
    if not isinstance(scene_table, dict):
        raise SceneFileError(path, ["a [scene] table is needed, with base = one of " + ", ".join(BASES)])
    base = scene_table.get("base", "planar_finger")
    if base not in BASES:
        raise SceneFileError(path, [f"base = {base!r}: choose one of {', '.join(BASES)}"])
    kwargs = {k: _value(f"[scene] {k}", v, problems) for k, v in scene_table.items() if k != "base"}
    unknown = sorted(set(data) - {"scene", "fingertip", "object", *SURFACES_3D})
    if unknown:
        problems.append(f"unknown tables {unknown}: the tables are [scene], and [fingertip] and "
                        "[object] (planar_finger) or [object_surface] (3D bases)")
    import grasping_sym as gs  # noqa: PLC0415

    if base == "planar_finger":
        curves = {k: _shape(k, data.get(k), _curve_functions(), problems) for k in ("fingertip", "object")}
        if problems:
            raise SceneFileError(path, problems)
        factory = lambda **kw: gs.scenes.planar_finger(curves["fingertip"], curves["object"], **kw)  # noqa: E731
    else:
        factory = getattr(gs.scenes, base)
        for k in SURFACES_3D:
            if k in data:
                if base == "paper2d":
                    problems.append(f"[{k}] is for the 3D bases, not {base}")
                    continue
                kwargs[k] = _shape(k, data[k], _surface_functions(), problems)
    if problems:
        raise SceneFileError(path, problems)
    try:
        return factory(**kwargs)
    except TypeError as exc:
        raise SceneFileError(path, [f"the keywords of {base}: {exc}"]) from None
    except ProblemsError as exc:  # the scene's own checks: with the file named
        raise SceneFileError(path, exc.problems) from None


def _value(where: str, value, problems: list[str]):
    """A TOML value with its text formulas as numbers; lists of names stay lists."""
    from grasping_sym.geometry.expressions import ExpressionError, parse_expression  # noqa: PLC0415

    if isinstance(value, bool) or isinstance(value, (int, float)):
        return value
    if isinstance(value, list):
        return tuple(_value(where, v, problems) if not isinstance(v, str) else v for v in value)
    if isinstance(value, str):
        if where.endswith(" name") or where.endswith(" shape"):
            return value
        try:
            number = float(parse_expression(value, {}))
        except (ExpressionError, TypeError) as exc:
            problems.append(f"{where} = {value!r}: {exc}")
            return math.nan
        return number
    problems.append(f"{where} = {value!r}: give a number, a formula as text, true/false or a list")
    return value


def _shape(table: str, spec, functions: dict, problems: list[str]):
    if not isinstance(spec, dict) or "shape" not in spec:
        problems.append(f"[{table}] needs shape = one of {', '.join(sorted(functions))}")
        return None
    shape = spec["shape"]
    if shape not in functions:
        problems.append(f"[{table}] shape = {shape!r}: choose one of {', '.join(sorted(functions))}")
        return None
    kwargs = {k: _value(f"[{table}] {k}", v, problems) for k, v in spec.items() if k != "shape"}
    if problems:
        return None
    try:
        return functions[shape](**kwargs)
    except TypeError as exc:
        problems.append(f"[{table}] {shape}: {exc}")
    except ProblemsError as exc:
        problems.append(f"[{table}] {shape}: {exc}")
    return None


def _curve_functions() -> dict:
    from grasping_sym.geometry import library  # noqa: PLC0415

    return {k: getattr(library, k) for k in library.__all__ if k[0].islower() and k != "spline"}


def _surface_functions() -> dict:
    from grasping_sym.geometry import surface_library  # noqa: PLC0415

    return {k: getattr(surface_library, k) for k in
            ("sphere", "ellipsoid", "superquadric", "plane", "torus")}
