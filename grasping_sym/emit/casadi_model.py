"""What the emitter takes: a model's CasADi functions (right-hand side, Jacobian, outputs,
constraints, start conditions, helpers), as one typed record. The assembly makes it
(``assemble.functions``, ``assemble.layered``), ``emit.cwriter`` writes its C."""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca


@dataclass
class CasadiModel:
    """The CasADi functions of one scene and the figures of merit of their graphs."""

    rhs: ca.Function
    jac: ca.Function
    outputs: ca.Function | None
    output_names: tuple[str, ...]
    op_counts: dict[str, int] = field(default_factory=dict)
    constraints: ca.Function | None = None
    #: ``names`` of the constraints, ``position_states`` (the states C depends on) and
    #: ``velocity_states`` (those Cdot depends on affinely and C not at all), by name index.
    constraint_info: dict = field(default_factory=dict)
    #: ``{name}_start`` ``(x, p) -> (G, dG_dx)``: every condition of a consistent contact
    #: (C and the tangency the update law keeps), for starts solved at run time.
    start: ca.Function | None = None
    start_names: tuple[str, ...] = ()
    #: further functions written into the C (a layered model's contour functions)
    helpers: tuple[ca.Function, ...] = ()
    #: the outputs of ``{name}_internal`` (a helper with the outputs' arguments): those only
    #: the run time reads, at a switch (an impact's ``W = A M^-1 A^T``), kept out of the
    #: outputs computed at every output time
    internal_names: tuple[str, ...] = ()

    def functions(self) -> list[ca.Function]:
        return [f for f in (self.rhs, self.jac, self.outputs, self.constraints, self.start,
                            *self.helpers) if f is not None]
