"""What a scene with contact modes takes from the scene it wraps (``model.planar_modes``,
``model.grasp3d_modes``): its name, controller, friction law and gravity; and how the wrapped
scene's rolling model runs the stretches where every contact rolls (``rolling_map``); and
which modes its compiled functions have branches of their own for (``folded_modes``,
``rhs_branches``)."""
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

    def rolling_map(self) -> dict | None:
        """How the base scene's rolling model (built with this scene by ``gs.build``) runs a
        stretch of a run in which every contact rolls (``runtime.modes``: the same equations,
        with its generated Jacobian and none of the other modes' branches): ``to``, the entry
        of this scene's state that each of the rolling model's is; ``from``, the rolling
        model's entry that each of this scene's is. Here the two states are one; None where
        no rolling model can run the scene (a subclass says)."""
        base, own = tuple(self.base.state_names), tuple(self.state_names)
        if base != own:
            return None
        return {"to": list(range(len(own))), "from": list(range(len(own)))}

    def folded_modes(self) -> tuple[int, ...]:
        """The contacts' modes (the numbers of ``mode{i}``) that the compiled outputs have a
        branch of their own for, with those modes folded in
        (``assemble.scene_functions.modes_functions``): every finger rolling, every surface of
        the world apart."""
        return (0,) * self.n_fingers + (2,) * (self.n_contacts - self.n_fingers)

    def rhs_branches(self) -> tuple[tuple[int, ...], ...]:
        """The contacts' modes that the compiled rhs has a branch of its own for, each with its
        modes folded in (``assemble.scene_functions.modes_functions``): with one contact, its
        sliding and its apart mode, and its rolling mode where the rolling model cannot run
        every rolling stretch (none, or one whose state is not this scene's: paper2d's shares
        ``u0 = u1``, which a slip ends); with more, where no rolling model runs them
        (``rolling_map``), ``folded_modes``; else none. Each branch costs gcc its instructions
        (paper2d's three: 0.6 s more of its 1.7 s build)."""
        where = self.rolling_map()
        if self.n_contacts == 1:
            whole = where is not None and where["to"] == where["from"] == list(range(len(self.state_names)))
            return ((1,), (2,)) if whole else ((0,), (1,), (2,))
        return (self.folded_modes(),) if where is None else ()
