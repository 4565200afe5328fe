"""Models in layers: a structure compiled once, a shape's own small C (2D: contours; 3D: surface jets).

The compiled layered functions are checked against the single-piece composition of the same
template with the same contours (``functions.compose``, evaluated by CasADi's virtual
machine, derivatives by CasADi's AD through the concrete contour expressions): the rhs, its
Jacobian (the state and parameter blocks), the outputs, the constraint function and the start
conditions with their Jacobians. Then: shapes on one structure share its compiled objects.
"""
from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.assemble import structure_cache
from grasping_sym.assemble.kinds import casadi_functions
from grasping_sym.assemble.scene_functions import planar_structure
from grasping_sym.pipeline import with_check_outputs


def _ellipse_scene(**kw):
    ellipse = gs.curves.ellipse(0.02, 0.015, start=math.pi, span=math.pi, clockwise=True)
    return gs.scenes.planar_finger(gs.curves.paper_fingertip(), ellipse, name="layers_ellipse",
                                   u1_0=math.pi + 0.3, **kw)


def _single_piece(scene):
    """The scene's functions composed in one piece from its template (no layers), with the
    outputs a build compiles: the scene's and those the run-time checks read."""
    return casadi_functions(with_check_outputs(scene)[0], layers=False).model


def _dense(v) -> np.ndarray:
    return np.array(ca.DM(v).full(), dtype=float)


def _two_finger_scene():
    """A second finger opposite the first (base mirrored about the pivot): a structure whose
    Jacobian is split in two (``structure.split_jacobian``)."""
    from grasping_sym.model.planar import ExtraFinger

    tip = gs.curves.circle(0.01, name="tip")
    ellipse = gs.curves.ellipse(0.025, 0.018, span=6.2, clockwise=True, name="ellipse")
    u1 = -(math.pi + 0.3)
    xm, _ = gs.scenes.planar_finger(tip, ellipse, name="one", u1_0=u1).pivot
    second = ExtraFinger(gs.curves.circle(0.01, name="tip2"), base=(2 * xm, 0.0), u1_0=0.35)
    return gs.scenes.planar_finger(tip, ellipse, name="layers_two", u1_0=u1, extra_fingers=(second,),
                                   outputs=("constraint_residual", "f1", "f2"))


@pytest.mark.parametrize("make", [
    lambda: _ellipse_scene(runtime=("fd", "I")),       # two contact parameters, run-time p
    lambda: replace(gs.scenes.paper2d(), name="layers_paper2d"),  # one shared, folded speed
    _two_finger_scene,                                 # the structure's Jacobian split in two
])
def test_layered_functions_equal_the_single_piece_composition(make):
    scene = make()
    model = gs.build(scene)
    assert "structure" in model.manifest
    record, _ = structure_cache.locate(model.manifest["structure"])
    split = "jac2" in record.functions
    assert split == (scene.n_fingers > 1)  # one finger's Jacobian is small enough to stay whole
    # the parts of a split Jacobian are compiled quick, each in its own file
    assert record.quick_files == (tuple(f"{record.name}_{k}.c" for k in (2, 3)) if split else ())
    one = _single_piece(scene)
    lib = str(model.library_path)
    ext = {k: ca.external(f"{scene.name}_{k}", lib) for k in ("rhs", "outputs", "constraints",
                                                            "start")}
    jac = ca.external(f"jac_{scene.name}_rhs", lib)
    p = np.asarray(model.default_params, float)
    rng = np.random.default_rng(7)
    x0 = np.asarray(model.initial_state(), float)
    for _ in range(4):
        x = x0 + rng.normal(0.0, 0.02, x0.size)
        a, b = _dense(ext["rhs"](0, x, [], p, [])[0]), _dense(one.rhs(0, x, [], p, [])[0])
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
        np.testing.assert_array_equal(a.ravel(), model.rhs(x))  # the driver calls the same code
        ja = jac(0, x, [], p, [], a, [], [], [])
        jb = one.jac(0, x, [], p, [], b, [], [], [])
        names = [jac.name_out(i) for i in range(jac.n_out())]
        assert names == [one.jac.name_out(i) for i in range(one.jac.n_out())]
        for block in ("jac_ode_x", "jac_ode_p"):
            k = names.index(block)
            A, B = _dense(ja[k]), _dense(jb[k])
            np.testing.assert_allclose(A, B, rtol=1e-10, atol=1e-10 * max(np.abs(B).max(), 1.0),
                                       err_msg=block)
        np.testing.assert_allclose(_dense(ext["outputs"](x, p)), _dense(one.outputs(x, p)),
                                   rtol=1e-12, atol=1e-12)
        for A, B in zip(ext["constraints"](x, p), one.constraints(x, p)):
            A, B = _dense(A), _dense(B)
            np.testing.assert_allclose(A, B, rtol=1e-10, atol=1e-10 * max(np.abs(B).max(), 1e-3))
        for A, B in zip(ext["start"](x, p)[:2], one.start(x, p)[:2]):
            A, B = _dense(A), _dense(B)
            np.testing.assert_allclose(A, B, rtol=1e-10, atol=1e-10 * max(np.abs(B).max(), 1e-3))
    assert model.manifest["constraints"]["position_states"] == [
        scene.state_names[i] for i in one.constraint_info["position_states"]]
    assert model.manifest["constraints"]["velocity_states"] == [
        scene.state_names[i] for i in one.constraint_info["velocity_states"]]


def test_shapes_on_one_structure_share_its_compiled_code():
    """Fingertips of other radii: the same structure (compiled once, from the cache on the
    second build), different models; the structure's name carries its hash."""
    base = gs.scenes.paper2d()
    a = gs.build(replace(base, name="layers_tip_a", fingertip=gs.curves.circle(0.011, name="tip")))
    b = gs.build(replace(base, name="layers_tip_b", fingertip=gs.curves.circle(0.013, name="tip")))
    assert a.manifest["structure"] == b.manifest["structure"]
    assert b.build_info["structure_source"] == "cache"
    assert a.manifest["structure"]["name"] == structure_cache.structure_name(
        a.manifest["structure"]["hash"])
    x = np.asarray(a.initial_state(), float)
    assert not np.array_equal(a.rhs(x), b.rhs(x, b.params()))  # the radius is in the shape's C
    ra, rb = a.simulate(0.5, method="radau"), b.simulate(0.5, method="radau")
    assert np.all(np.isfinite(ra.x)) and np.all(np.isfinite(rb.x))


def test_structure_records_read_and_write_the_committed_files_unchanged(tmp_path):
    """``structure.json`` of every committed structure (2D and 3D) is read into a typed
    record (slots, what each function reads) and written back as the same bytes; a record
    lacking a field is refused by name."""
    from grasping_sym.assemble.structure import CONTOUR_LEAVES, SURFACE_JETS
    from grasping_sym.store import files as stored
    from grasping_sym.store import safety
    from grasping_sym.store.paths import generated_dir

    paths = sorted((generated_dir() / structure_cache.DIR).glob(f"*/{structure_cache.META}"))
    layouts = set()
    for path in paths:
        record = structure_cache.StructureRecord.from_json(json.loads(path.read_text()))
        layouts.add(record.layout)
        assert record.name == path.parent.name
        assert all(set(by_input) <= {"L", "dL", "tau", "J"} for by_input in record.reads.values())
        if record.layout is CONTOUR_LEAVES:
            assert all(len(slot.states) == 1 for slot in record.slots)
        else:
            assert all(len(slot.states) == 2 and slot.entries == tuple(range(len(slot.entries)))
                       for slot in record.slots)
            assert set(record.reads["rhs"]) == {"J"}
        copy = stored.write_json(tmp_path / f"{record.name}.json", record.to_json())
        assert copy.read_bytes() == path.read_bytes(), path
    assert layouts == {CONTOUR_LEAVES, SURFACE_JETS}
    data = json.loads(paths[0].read_text())
    del data["slots"]
    with pytest.raises(safety.CorruptCacheError, match="slots"):
        structure_cache.StructureRecord.from_json(data)


def test_unit_speed_leaves_are_folded_into_the_structure():
    spec, leaves = planar_structure(gs.scenes.paper2d())
    # fingertip and object of paper2d run at unit speed: speed = 1, dspeed = 0 in both slots
    # (leaves: X, Y, Tx, Ty, speed, kappa, dspeed, dkappa)
    assert [dict(f) for f in spec.folded] == [{4: 1, 6: 0}, {4: 1, 6: 0}]
    circle = replace(gs.scenes.paper2d(), fingertip=gs.curves.circle(0.011, name="tip"))
    spec_c, _ = planar_structure(circle)
    assert dict(spec_c.folded[0]) == {4: 1, 6: 0, 7: 0}  # a circle's curvature is constant
    spec_e, _ = planar_structure(_ellipse_scene())
    assert dict(spec_e.folded[1]) == {}  # the ellipse: nothing constant


# ------------------------------------------------------------------------------ 3D
def _surface_pair_scene(name: str, semi_axes=(0.022, 0.025, 0.028), tip=0.009, **kw):
    import dataclasses

    from grasping_sym.geometry import surface_library as sl
    base = gs.scenes.paper3d()
    return gs.scenes.paper3d(
        name=name, object_surface=sl.ellipsoid(*semi_axes, lon=(-math.pi / 2, 3 * math.pi / 2),
                                               name="object"),
        fingers=tuple(dataclasses.replace(f, tip=sl.sphere(tip, name=f"tip{i}"))
                      for i, f in enumerate(base.fingers)), **kw)


def test_3d_layered_functions_equal_the_single_piece_derivation():
    """paper3d in layers (structure with the surfaces' jets as inputs) against the single
    piece (surfaces and CasADi's AD in one graph): rhs, outputs, constraint function, start
    conditions and their Jacobians."""
    scene = replace(gs.scenes.paper3d(), name="layers_paper3d")
    model = gs.build(scene)
    assert "structure" in model.manifest
    one = _single_piece(scene)
    lib = str(model.library_path)
    ext = {k: ca.external(f"{scene.name}_{k}", lib) for k in ("outputs", "constraints", "start")}
    p = np.asarray(model.default_params, float)
    rng = np.random.default_rng(11)
    x0 = np.asarray(model.initial_state(), float)
    for _ in range(3):
        x = x0 + rng.normal(0.0, 1e-3, x0.size)
        b = _dense(one.rhs(0, x, [], p, [])[0]).ravel()
        np.testing.assert_allclose(model.rhs(x), b, rtol=1e-11, atol=1e-11 * np.abs(b).max())
        np.testing.assert_allclose(_dense(ext["outputs"](x, p)), _dense(one.outputs(x, p)),
                                   rtol=1e-11, atol=1e-12)
        for name in ("constraints", "start"):
            for A, B in zip(ext[name](x, p), getattr(one, name)(x, p)):
                A, B = _dense(A), _dense(B)
                np.testing.assert_allclose(A, B, rtol=1e-11,
                                           atol=1e-11 * max(np.abs(B).max(initial=0.0), 1e-3),
                                           err_msg=name)


def test_the_3d_rhs_reads_the_outputs_jets_and_the_scene_writes_them_once():
    """paper3d's rhs needs 264 jet entries and its outputs 4 more: the structure's rhs reads
    the outputs' 268 (``structure3d._widen``), so the scene's C holds one jets function for
    both (the previous test checks their numbers); a wider difference keeps them apart."""
    from grasping_sym.assemble import structure3d

    model = gs.build(replace(gs.scenes.paper3d(), name="layers_paper3d"))
    source = "".join(f.read_text() for f in sorted(model.library_path.parent.glob("layers_paper3d_*.c")))
    assert "layers_paper3d_jets_rhs:(x[33])->(J[268x1" in source
    assert "layers_paper3d_jets_outputs" not in source
    assert structure3d._widen(list(range(264)), list(range(268)))
    assert not structure3d._widen(list(range(200)), list(range(268)))  # 68 more: kept apart
    assert not structure3d._widen([*range(263), 300], list(range(268)))  # not a subset


def test_a_new_3d_surface_pair_reuses_the_structure():
    """Other surfaces, and another object mass and inertia (inputs of the structure, after
    the jets): the same compiled structure, and the rhs of the single piece derived with
    those numbers as constants (1e-11)."""
    from grasping_sym.model.inertia import solid_ellipsoid_inertia

    a = gs.build(_surface_pair_scene("layers_pair_a"))
    scene_b = _surface_pair_scene("layers_pair_b", semi_axes=(0.021, 0.026, 0.03), tip=0.01, mass=0.055,
                                  inertia=solid_ellipsoid_inertia(0.055, 0.021, 0.026, 0.03))
    b = gs.build(scene_b)
    assert a.manifest["structure"] == b.manifest["structure"]
    assert b.build_info["structure_source"] == "cache"
    one, p = _single_piece(scene_b), np.asarray(b.default_params, float)
    x0 = np.asarray(b.initial_state(), float)
    for x in (x0, x0 + np.random.default_rng(2).normal(0.0, 1e-3, x0.size)):
        ref = _dense(one.rhs(0, x, [], p, [])[0]).ravel()
        np.testing.assert_allclose(b.rhs(x), ref, rtol=1e-11, atol=1e-11 * np.abs(ref).max())
    res = b.simulate(0.2, method="dopri5", project=True, rtol=1e-8, atol=1e-11)
    assert np.all(np.isfinite(res.x)) and res.outputs["constraint_residual"].max() < 1e-9


def test_a_full_inertia_reaches_the_structure_whole():
    """``body_values`` and the structure's reading of them (``_body``) give back a full
    (non-diagonal) inertia and the mass exactly; a diagonal one is read from 4 entries."""
    from grasping_sym.assemble import structure3d

    rot = np.array(gs.scenes._axis_angle((1.0, 2.0, 3.0), 0.7))
    H = rot @ np.diag([2e-5, 3e-5, 4e-5]) @ rot.T
    values = structure3d.body_values(0.07, H)
    assert len(values) == 7 and structure3d.inertia_pattern(H) == "full"
    m, H_sx = structure3d._body(ca.DM(values), "full")
    assert float(m) == 0.07 and np.array_equal(np.asarray(ca.DM(H_sx)), np.array([[H[0, 0], H[0, 1], H[0, 2]],
                                                                                   [H[0, 1], H[1, 1], H[1, 2]],
                                                                                   [H[0, 2], H[1, 2], H[2, 2]]]))
    diag = structure3d.body_values(0.07, np.diag([1.0, 2.0, 3.0]))
    assert diag == [0.07, 1.0, 2.0, 3.0]


def test_quick_files_compile_at_og_and_the_others_at_o2(tmp_path, monkeypatch):
    """``compile_objects(quick=...)``: the files named compile with ``QUICK_FLAGS`` (last, so
    they override -O2), the others with the base flags only (at the full level: the suite's is
    none, conftest)."""
    from grasping_sym.toolchain import compiler

    monkeypatch.setenv("GRASPING_SYM_OPT", "full")
    commands = []
    monkeypatch.setattr(compiler, "_run_all",
                        lambda jobs, at_once=None: commands.extend(cmd for cmd, _ in jobs))
    a, b = tmp_path / "a.c", tmp_path / "b.c"
    for f in (a, b):
        f.write_text("int f(void) { return 0; }\n")
    compiler.compile_objects([a, b], tmp_path, quick=[b])
    flags = {Path(cmd[cmd.index("-c") + 1]).name: cmd for cmd in commands}
    assert compiler.QUICK_FLAGS == ("-Og",)
    assert "-Og" not in flags["a.c"] and "-O2" in flags["a.c"]
    assert flags["b.c"].index("-Og") > flags["b.c"].index("-O2")


@pytest.fixture(scope="module")
def empty_cache(tmp_path_factory):
    """A cache of this module's own, empty at its first build: the three models below derive
    everything, and share the driver's objects where their work sizes do."""
    return tmp_path_factory.mktemp("predict")


@pytest.mark.parametrize("make", [
    lambda: replace(gs.scenes.paper2d(), name="layers_predict_2d"),
    _two_finger_scene,
    lambda: _surface_pair_scene("layers_predict_3d"),
])
def test_the_driver_objects_compiled_ahead_are_the_models(make, monkeypatch, empty_cache):
    """A build that derives a structure predicts its driver's macros first and compiles their
    objects meanwhile (``library.predicted_defines``): the prediction is the model's own,
    so the objects it makes are the ones the model links."""
    from grasping_sym.toolchain import library, objects

    monkeypatch.setenv("GRASPING_SYM_CACHE", str(empty_cache))  # no model of these cached: all derived
    predicted = []
    real = library.prefetch_driver
    monkeypatch.setattr(library, "prefetch_driver",
                        lambda defines, fast=True: (predicted.append(defines), real(defines, fast)))
    with structure_cache.derive_afresh():  # not copied from the committed structures
        model = gs.build(make())
    assert model.build_info["structure_source"].startswith("derived")
    assert len(predicted) == 1
    assert (objects.object_defines(predicted[0])
            == objects.object_defines(model.manifest["driver_defines"]))
