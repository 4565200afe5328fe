"""The kinds of scene: one registry, asked by every floor above instead of the dimension.

A scene class names its kind (``kind``: ``"planar"``, ``"grasp3d"``) and meets the scene
protocol (``model.protocol.Scene``). Each floor that treats kinds differently keeps one table
keyed by the kind's name (``assemble.kinds``: how a kind is derived and assembled;
``viz.kinds``: how its runs are drawn) and looks a scene up with ``of``: a new kind of scene
is a class here and one row in each table.
"""
from __future__ import annotations

from grasping_sym.errors import InvalidSceneError

#: Every kind of scene: its name -> what it is.
KINDS: dict[str, str] = {
    "planar": "2D: planar two-joint fingers rolling on an object pivoted at a point (model.planar)",
    "grasp3d": "3D: spatial finger chains grasping an object with smooth surfaces (model.grasp3d)",
    "body": "3D: a free body on a plane of the world, rolling, sliding or separated (model.body)",
    "body2d": "2D: a free body on a line of the world, rolling, sliding or separated (model.body_line)",
    "grasp3d_modes": "3D: a grasp whose finger contacts roll, slide or separate (model.grasp3d_modes)",
    "planar_modes": "2D: planar fingers whose contacts roll, slide or separate (model.planar_modes)",
}


def of(scene, table: dict, what: str):
    """The row of ``table`` (keyed by kind name) for ``scene``; a named error when ``scene``
    is not a scene of a known kind, or ``table`` has no row for it."""
    kind = getattr(type(scene), "kind", None)
    if kind not in KINDS:
        raise InvalidSceneError([
            f"{type(scene).__name__} is not a scene of a known kind ({', '.join(KINDS)}): make one "
            "with gs.scenes (e.g. gs.scenes.paper2d(), gs.scenes.planar_finger(...), gs.scenes.paper3d())"])
    if kind not in table:
        raise InvalidSceneError([f"{what} is not available for {kind} scenes ({KINDS[kind]})"])
    return table[kind]
