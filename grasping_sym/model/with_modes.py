"""What a scene with contact modes takes from the scene it wraps (``model.planar_modes``,
``model.grasp3d_modes``): its name, controller, friction law and gravity."""
from __future__ import annotations

from typing import ClassVar


class WithModes:
    """A scene with modes over ``self.base``: the parts it shares with the base scene."""

    #: No control inputs: the modes' run-time parameters are their own (``runtime.modes``).
    input_names: ClassVar[tuple[str, ...]] = ()

    @property
    def name(self) -> str:
        return f"{self.base.name}_modes"

    @property
    def controller(self):
        return self.base.controller

    @property
    def friction(self):
        return self.base.friction

    @property
    def gravity(self):
        return self.base.gravity
