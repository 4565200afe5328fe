"""What every drawing of a run checks before it starts: the scene is the run's, and each
option is one the drawing knows (``gs.viz.animate``, ``gs.viz.view``)."""
from __future__ import annotations

import inspect

from grasping_sym.errors import ViewOptionError
from grasping_sym.runtime.result import names_text


def known_options(draw, what: str, options: dict) -> None:
    """``options`` are keyword options of ``draw`` (``animate`` or ``write_viewer``)."""
    known = [n for n, p in inspect.signature(draw).parameters.items() if p.kind is p.KEYWORD_ONLY]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ViewOptionError(f"{what}: unknown option(s) {unknown}; the options are {known}")


def check_scene(result, scene, what: str) -> None:
    """Before a drawing of ``result`` starts: ``scene`` has the result's states (a result drawn
    with another scene's geometry would fail inside it, or draw something else)."""
    names = getattr(scene, "state_names", None)
    if names is not None and tuple(names) != tuple(result.state_names):
        raise ViewOptionError(
            f"{what}: the scene {getattr(scene, 'name', '?')!r} has the states "
            f"{names_text(tuple(names))}, the result {names_text(tuple(result.state_names))}: pass the "
            "scene the result was run on")

