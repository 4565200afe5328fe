"""Templates: one SymPy derivation per scene structure, composed with any shape."""
from __future__ import annotations

import math

import numpy as np

import grasping_sym as gs
from grasping_sym.assemble import templates
from grasping_sym.assemble.controller import controller_function
from grasping_sym.assemble.functions import Template, build_casadi, compose
from grasping_sym.derive.planar import derive_planar, parameter_values
from grasping_sym.store.templates import committed_templates_dir


def _ellipse_scene(**kw):
    ellipse = gs.curves.ellipse(0.02, 0.015, start=math.pi, span=math.pi, clockwise=True)
    return gs.scenes.planar_finger(gs.curves.paper_fingertip(), ellipse, name="tpl_ellipse",
                                   u1_0=math.pi + 0.3, **kw)


def test_every_structure_has_a_committed_template():
    for shared, gravity in templates.PLANAR_STRUCTURES:
        name = templates.template_name(shared, gravity)
        assert (committed_templates_dir() / f"{name}.json").is_file(), name


def test_new_shape_is_composed_without_derivation():
    """A new object shape on a committed structure: no SymPy derivation of the closed loop
    (the structure comes from a template in the cache or committed, or the structure itself
    from the cache)."""
    model = gs.build(_ellipse_scene())
    assert model.build_info["source"] == "derived"
    assert model.build_info["structure_source"] in (
        "cache", "committed", "derived (template: committed)", "derived (template: cache)")


def test_serialized_template_composes_to_the_same_functions():
    scene = _ellipse_scene(runtime=("fd",))
    system = derive_planar(scene)
    direct = build_casadi(system, scene.fingertip, scene.object, "direct")
    tpl, _ = templates.planar_template(scene.shared_parameter, False)
    again = Template.from_json(tpl.to_json())
    values = parameter_values(scene)
    # the composed closed loop takes its torques from the controller layer (CasADi), the
    # direct one from the SymPy statement of law (32) (derive_planar): two paths, one law
    runtime = scene.p_names
    composed = compose(again, scene.fingertip, scene.object, runtime=runtime,
                       constants={k: v for k, v in values.items() if k not in runtime},
                       outputs=scene.outputs, name="composed",
                       controller=controller_function(scene, "composed"))
    rng = np.random.default_rng(3)
    x0 = scene.initial_state()
    for _ in range(5):
        x = x0 + rng.normal(size=x0.size) * 0.01
        a = np.array(direct.rhs(0, x, [], [0.5], [])[0]).ravel()
        b = np.array(composed.rhs(0, x, [], [0.5, *scene.pivot], [])[0]).ravel()
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13 * np.abs(a).max())


def test_gravity_structure_only_when_gravity_is_modelled():
    horizontal = derive_planar(_ellipse_scene())
    assert "gx" not in {str(s) for s in [*horizontal.params, *horizontal.constants]}
    zero = derive_planar(_ellipse_scene(gravity=(0.0, 0.0)))  # zero gravity: no terms at all
    assert "gx" not in {str(s) for s in [*zero.params, *zero.constants]}
    heavy = derive_planar(_ellipse_scene(gravity=(0.0, -9.81)))
    assert {"gx", "gy"} <= {str(s) for s in heavy.constants}
