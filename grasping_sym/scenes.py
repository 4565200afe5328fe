"""Built-in scenes. Each is a plain function returning a scene; every value is a keyword."""
from __future__ import annotations

import math

from grasping_sym.geometry import library
from grasping_sym.geometry.curves import PlanarCurve
from grasping_sym.model.planar import DEFAULT_OUTPUTS, PlanarFingerScene

#: Paper Tables 1 and 2 plus the choices of MODELS.md section 1 (SI units).
PAPER2D_PARAMS: dict[str, float] = {
    "l11": 0.065, "l12": 0.065, "m11": 0.045, "m12": 0.040,
    "I": 0.040 * 0.02**2 / 2,          # M r^2 / 2 with M = 0.040 kg, r = 0.02 m
    "fd": 0.5, "c": 0.006, "r": 0.010,
    "gf": 1500.0, "gl": 3000.0, "wf": 225.0e4, "wl": 900.0e4,
}


def planar_finger(
    fingertip: PlanarCurve,
    object: PlanarCurve,  # noqa: A002 - the paper's word
    *,
    name: str = "planar",
    runtime: tuple[str, ...] = (),
    outputs: tuple[str, ...] = DEFAULT_OUTPUTS,
    gravity: tuple[float, float] | None = None,
    q1_0: float = math.pi / 6,
    theta_0: float = 0.0,
    u0_0: float = 0.0,
    u1_0: float = 0.0,
    **params: float,
) -> PlanarFingerScene:
    """The general 2D scene with any two contours; unspecified parameters from the paper."""
    values = dict(PAPER2D_PARAMS)
    values.update(params)
    return PlanarFingerScene(
        name=name, fingertip=fingertip, object=object, params=values, runtime=runtime,
        outputs=outputs, gravity=gravity, q1_0=q1_0, theta_0=theta_0, u0_0=u0_0, u1_0=u1_0,
    )


def paper2d(**overrides) -> PlanarFingerScene:
    """Yoshida-Arimoto-Tahara 2009: the paper's catenary fingertip and object (MODELS.md 1).

    Any argument of ``planar_finger`` (contours, parameters, initial state, ``runtime``,
    ``outputs``) may be overridden by keyword.
    """
    kwargs = {"fingertip": library.paper_fingertip(), "object": library.paper_object(),
              "name": "paper2d"}
    kwargs.update(overrides)
    return planar_finger(**kwargs)


#: Built-in scenes by name, for the CLI.
BUILTIN = {"paper2d": paper2d}
