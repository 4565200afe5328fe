"""Scenes from TOML files: a built-in scene with its keywords changed, or a 2D finger on shapes
from the library, with numbers written as formulas that are parsed, never run.

```toml
[scene]
base = "planar_finger"          # or a built-in: paper2d, pinch2d, paper3d, pivot3d
name = "my_ellipse"
q1_0 = "pi / 6"                 # any keyword of the base; text is a formula (numbers, pi, E,
u1_0 = "pi + 0.3"               # + - * / **, sqrt, sin, cos, ...)
runtime = ["fd"]
inputs = "torques"              # joint torques u1, u2, ... added to the law (model.control)
controller = "paper"            # the paper's law (default), or "none": the torques are the inputs

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

A formula is computed in floating point (``geometry.expressions.evaluate_number``: ``"pi / 6"``
is ``math.pi / 6``), within the reader's limits (a formula like ``"10**10**10"`` is refused at
once). The keys :data:`TEXT_KEYS` take text as it is (``name = "pi"`` is a name). A file is
UTF-8 text of at most :data:`MAX_BYTES` bytes, a regular file (not a device or a pipe).
"""
from __future__ import annotations

import math
import os
import stat
import tomllib
from pathlib import Path

from grasping_sym.errors import ProblemsError
from grasping_sym.geometry import library, surface_library
from grasping_sym.geometry.expressions import ExpressionError, evaluate_number
from grasping_sym.model import scenes


class SceneFileError(ProblemsError):
    """A scene file that cannot be read: every problem, with the file."""

    def __init__(self, path, problems: list[str]):
        self.path = path
        super().__init__(f"scene file {path}", problems)


#: The bases a file may name.
BASES = ("planar_finger", "paper2d", "pinch2d", "paper3d", "pivot3d")
#: Surface tables of a 3D file: the base's keyword each one sets.
SURFACES_3D = ("object_surface",)
#: Keys of [scene] whose text is a word, not a formula (in a shape table: ``name``, ``shape``).
TEXT_KEYS = ("name", "inputs", "controller", "formulation", "support")
#: The largest scene file read (bytes).
MAX_BYTES = 1 << 20
#: ``controller = ...`` in a file: the scene's keyword each word stands for.
CONTROLLERS = {"paper": "paper", "none": None}


def load_scene(path: str | Path):
    """The scene the TOML file at ``path`` describes (module docstring)."""
    path = Path(path)
    try:
        data = tomllib.loads(_read_text(path))
    except tomllib.TOMLDecodeError as exc:
        raise SceneFileError(path, [f"not valid TOML: {exc}"]) from None
    except RecursionError:
        raise SceneFileError(path, ["not valid TOML here: its arrays or tables are nested too "
                                    "deeply to read; a scene file nests them at most two deep"]) from None
    problems: list[str] = []
    scene_table = data.get("scene")
    if not isinstance(scene_table, dict):
        raise SceneFileError(path, ["a [scene] table is needed, with base = one of " + ", ".join(BASES)])
    base = scene_table.get("base", "planar_finger")
    if base not in BASES:
        raise SceneFileError(path, [f"base = {base!r}: choose one of {', '.join(BASES)}"])
    kwargs = {k: _value(f"[scene] {k}", v, problems, text=k in TEXT_KEYS)
              for k, v in scene_table.items() if k != "base"}
    if isinstance(kwargs.get("controller"), str):
        word = kwargs["controller"]
        if word in CONTROLLERS:
            kwargs["controller"] = CONTROLLERS[word]
        else:
            problems.append(f"[scene] controller = {word!r}: choose one of {list(CONTROLLERS)} "
                            "(a law of your own is written in Python: gs.controllers)")
    unknown = sorted(set(data) - {"scene", "fingertip", "object", *SURFACES_3D})
    if unknown:
        problems.append(f"unknown tables {unknown}: the tables are [scene], and [fingertip] and "
                        "[object] (planar_finger) or [object_surface] (3D bases)")

    if base == "planar_finger":
        curves = {k: _shape(k, data.get(k), _curve_functions(), problems) for k in ("fingertip", "object")}
        if problems:
            raise SceneFileError(path, problems)
        factory = lambda **kw: scenes.planar_finger(curves["fingertip"], curves["object"], **kw)  # noqa: E731
    else:
        factory = getattr(scenes, base)
        problems += [f"[{k}] is for base = \"planar_finger\" (a built-in base has its own contours): "
                     f"give base = \"planar_finger\" with [fingertip] and [object], or leave [{k}] out"
                     for k in ("fingertip", "object") if k in data]
        for k in SURFACES_3D:
            if k in data:
                if base in ("paper2d", "pinch2d"):
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


def _read_text(path: Path) -> str:
    """The text of the file at ``path``: a regular file of at most MAX_BYTES bytes, UTF-8."""
    try:  # opened without blocking (a FIFO), then checked on the open file (no race)
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise SceneFileError(path, [f"cannot read it: {exc.strerror}"]) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise SceneFileError(path, ["it is not a regular file (a directory, a device such as "
                                        "/dev/zero, a pipe, ...): give the path of a .toml file"])
        if info.st_size > MAX_BYTES:
            raise SceneFileError(path, [f"it has {info.st_size} bytes: a scene file has at most "
                                        f"{MAX_BYTES} (1 MiB); is it the right file?"])
        chunks, size = [], 0
        while size <= MAX_BYTES:
            chunk = os.read(fd, MAX_BYTES + 1 - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        raw = b"".join(chunks)
    except OSError as exc:
        raise SceneFileError(path, [f"cannot read it: {exc.strerror}"]) from None
    finally:
        os.close(fd)
    if len(raw) > MAX_BYTES:
        raise SceneFileError(path, [f"it has more than {MAX_BYTES} bytes (1 MiB): a scene file "
                                    "is smaller; is it the right file?"])
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneFileError(path, [f"it is not UTF-8 text: byte {exc.start} ({raw[exc.start]:#04x}) "
                                    "cannot be decoded; save the file as UTF-8 (TOML is UTF-8)"]) from None


def _value(where: str, value, problems: list[str], text: bool = False):
    """A TOML value with its text formulas as numbers (``text``: a word, kept as it is); lists
    keep their text."""
    if isinstance(value, bool) or isinstance(value, int):
        return value
    if isinstance(value, float):
        if not math.isfinite(value):
            problems.append(f"{where} = {value}: give a finite number")
        return value
    if isinstance(value, list):
        return tuple(_value(where, v, problems) if not isinstance(v, str) else v for v in value)
    if isinstance(value, str):
        if text or where.endswith(" name") or where.endswith(" shape"):
            return value
        try:
            return evaluate_number(value)
        except ExpressionError as exc:
            why = str(exc).removeprefix(f"{value!r}: ")  # the formula is named once
            problems.append(f"{where} = {_clip(value)}: {why}")
            return math.nan
    problems.append(f"{where} = {_clip(value)}: give a number, a formula as text, true/false or a list")
    return value


def _clip(value, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}..."


def _shape(table: str, spec, functions: dict, problems: list[str]):
    if not isinstance(spec, dict) or "shape" not in spec:
        problems.append(f"[{table}] needs shape = one of {', '.join(sorted(functions))}")
        return None
    shape = spec["shape"]
    if not isinstance(shape, str) or shape not in functions:
        problems.append(f"[{table}] shape = {_clip(shape)}: choose one of {', '.join(sorted(functions))} "
                        "(one name, as text)")
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

    return {k: getattr(library, k) for k in library.__all__ if k[0].islower() and k != "spline"}


def _surface_functions() -> dict:

    return {k: getattr(surface_library, k) for k in
            ("sphere", "ellipsoid", "superquadric", "plane", "torus")}
